"""The HDF5 session store: schema v1, the recorder thread, checking and repairing files."""

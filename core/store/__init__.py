"""The HDF5 session store: schema v2 (reads v1), the recorder thread, checking and repairing files."""

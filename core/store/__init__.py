"""The HDF5 session store, the only package that imports h5py: schema v2 (reads v1), the session's file
(:mod:`.session_file`) and its read API (:mod:`.reader`), the recorder thread, checking and repairing files."""

"""Demonstrations: running the scripted demonstrator, and the HDF5 files that hold them."""

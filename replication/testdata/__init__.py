"""Independent test-data generators (no imports from the rest of ``replication``)."""

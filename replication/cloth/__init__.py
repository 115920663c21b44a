"""Paper section 3: Provot's mass-spring cloth, its costs, data I/O and identification."""

"""Independent reference implementations the vectorised core is checked against (SPEC §7)."""

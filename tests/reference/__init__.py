"""Independent reference implementations the vectorised core is checked against
(README "How correctness is checked")."""

"""Contact kernels (pure numpy): search, master curves, mortar and node-to-segment integrals."""

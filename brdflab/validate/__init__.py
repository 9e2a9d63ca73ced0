"""Statistical validation of materials and warps: chi-square, consistency, furnace, stability."""

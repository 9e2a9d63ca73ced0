"""Judging a BSDF: its sampler against its pdf (``chi2``), weight = eval·cos/pdf and reciprocity
(``consistency``), energy (``furnace``), extreme directions (``stability``); ``battery`` runs them over grids of
parameters and angles (``entries``: the built-ins' grids)."""

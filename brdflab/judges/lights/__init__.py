"""Judging brdflab's own light samplers: chi-square of area lights, the fused light set and environment maps, and
``sample().pdf`` equal to the density of a hit (``samplers``)."""

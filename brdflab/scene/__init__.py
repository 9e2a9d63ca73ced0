"""Nori XML parsing, property lists, OBJ loading and scene assembly."""

"""Emitters: mesh area lights, point lights and environment maps."""

"""Integrators: ``normals``, ``direct_ems``, ``direct_mats``, ``direct_mis`` (shared helpers in common)."""

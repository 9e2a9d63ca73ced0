"""Nori XML parsing, property lists, OBJ loading and scene assembly."""

from pathlib import Path

#: The bundled scenes (``scenes/`` beside the package in a source checkout; absent from a wheel).
BUNDLED_SCENES = Path(__file__).resolve().parents[2] / "scenes"

"""Frames, transforms and warps (sample + pdf pairs)."""

"""Integrators: ``normals``, the direct ones (``direct_ems``, ``direct_mats``, ``direct_mis``, ``direct_whitted``)
and the path tracers (``path``, ``path_nee``, ``path_mis``: :mod:`~brdflab.integrator.wavefront`); shared helpers in
``common``."""

"""brdflab — a BRDF validation and visualisation workbench.

Renders Nori scene files under direct illumination with microfacet materials (NumPy-vectorised over
embreex ray queries), validates every material and sampling routine statistically, and compares Monte
Carlo estimators as error against run time.
"""

__version__ = "0.1.0"

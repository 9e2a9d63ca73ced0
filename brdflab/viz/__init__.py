"""BRDF visualisation: the views of Disney's BRDF Explorer for brdflab's materials and users' plugins.

* :mod:`brdflab.viz.coords` — directions in the plane of incidence and Rusinkiewicz's half/difference
  angles (θ_h, φ_h, θ_d, φ_d), both ways.
* :mod:`brdflab.viz.views` — the data of each view (NumPy, one vectorised ``eval`` per BSDF and view).
* :mod:`brdflab.viz.figures` — matplotlib figures of the views (PNG and SVG).
* :mod:`brdflab.viz.sphere` — a sphere of the material rendered by brdflab's own integrators.
* :mod:`brdflab.viz.static` — ``brdflab plot``: every view, its CSV data and a self-contained index.html.
* :mod:`brdflab.viz.explorer` — ``brdflab explore``: the live, linked views in a browser (Bokeh server).
"""

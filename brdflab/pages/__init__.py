"""HTML pages and their figures: the variance study (``brdflab report``), check, chi-square and validation pages.

``bl.report(...)`` is :func:`brdflab.workflows.report`, which writes its page through this package.
"""

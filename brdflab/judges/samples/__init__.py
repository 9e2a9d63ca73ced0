"""Judging samples written by another renderer (``brdflab chi2 --samples FILE``).

BSDF samples: ``tables`` reads the files, ``bsdf_checks`` compares them with brdflab's model, ``selfconsistency``
judges them against their own pdf, ``bsdf_hints`` names the usual bugs, ``bsdf_results`` holds the verdicts.
Light samples (``--against-emitter``): ``light_samples`` reads them and gives the verdict, ``light_checks`` holds
the checks.
"""

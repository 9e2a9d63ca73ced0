"""HTML pages and their figures: the variance study (``brdflab report``), check, chi-square and validation pages.

``bl.report(...)`` is :func:`brdflab.workflows.report`: this package is also callable under that name (the
package and the function share the name ``report`` on :mod:`brdflab`, so the package forwards a call).
"""

from brdflab.callable_modules import make_callable

make_callable(__name__, "brdflab.workflows:report")

"""The judges' shared machinery: bins on the sphere (``binning``), adaptive quadrature (``quadrature``), one random
stream per test (``seeding``), the guard that turns a raising plugin into a failed verdict (``guard``), the grouping
of failures by cause (``failures``) and result lists (``results``)."""

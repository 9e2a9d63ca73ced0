"""Judging estimators: integrators of one scene must agree within statistical error (``agreement``)."""

"""What a judge of others' numbers must know about their precision: rounding is never a bug.

Every Nori build computes in float32, and files are often printed with 6–9 significant digits. A column computed in
float32 carries relative errors of a few units of 2⁻²⁴ (≈ 6·10⁻⁸) per operation, and these need not average out:
a pdf evaluated in float32 was measured 1.2·10⁻⁷ low on average over 80 000 samples of a correct student sampler.
When the sampler is brdflab's own method, the ratio r/p of brdflab's density to the file's is 1 up to that rounding,
the sample variance of a total collapses to the rounding's, and a test without a floor calls 10⁻⁷ "significant"
(z = −54.8 for a correct uniform-area light sampler).

Every z-test of a total or a mean of ratios read from a file adds :func:`rounding_variance` to its variance: a
relative difference below :data:`ROUNDING_UNITS` units of the data's precision is rounding, never evidence. A real
bug (a missing Jacobian, a wrong factor) is off by 10⁻³ or more, so the floor costs no power where it matters.
"""

from __future__ import annotations

import numpy as np

#: Relative precision of a float32 value (half an ulp at 1).
FLOAT32_EPS = 2.0**-24
#: How many units of the precision a float32 computation chain of a few operations may be off systematically.
ROUNDING_UNITS = 16


def rounding_variance(expected, eps: float = FLOAT32_EPS):
    """The variance floor of a test of a quantity whose true value is ``expected``, read at relative precision
    ``eps`` (default float32): (ROUNDING_UNITS · eps · |expected|)², element-wise for an array.

    Examples
    --------
    >>> round(rounding_variance(1.0) ** 0.5 * 1e7, 2)  # about 1e-6 relative
    9.54
    """
    v = (ROUNDING_UNITS * eps * np.abs(expected)) ** 2
    return float(v) if np.ndim(v) == 0 else v

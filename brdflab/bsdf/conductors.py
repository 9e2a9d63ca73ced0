"""Complex refractive indices η + ik of metals, converted to the renderer's linear-sRGB channels.

Data (facts, tabulated by photon energy and converted to wavelength by λ[nm] = 1239.84193/E[eV]):
H.-J. Hagemann, W. Gudat and C. Kunz, "Optical constants from the far infrared to the x-ray region: Mg, Al, Cu,
Ag, Au, Bi, C, and Al2O3", DESY report SR-74/7 (1974), doi:10.3204/PUBDB-2018-00701 (Au: table 5; Ag, Al, Cu:
table 3), the rows covering the visible range. The copper table available here ends at 670.2 nm; above it the
last row is held (the colour-matching functions there carry < 2 % of Y).

Conversion (brdflab's choice, stated): η(λ) and k(λ) are interpolated linearly (held constant beyond the table)
at 380–780 nm in 5 nm steps, each integrated against the CIE 1931 2° colour-matching functions (from
colour-science) with weights normalised so that a constant spectrum c gives XYZ = c·(X_E, 1, Z_E) (illuminant E),
then mapped to linear sRGB with a Bradford adaptation from E to D65, so a constant spectrum gives the grey
(c, c, c). η and k are converted separately (as a spectral renderer's RGB mode does), not the reflectance.
"""

from __future__ import annotations

import functools

import numpy as np

#: (λ nm, η, k) rows per metal (Hagemann, Gudat and Kunz 1974; see the module docstring).
TABLES: dict[str, tuple[tuple[float, float, float], ...]] = {
    "Au": ((344.4, 2.024, 1.81), (359.3, 1.967, 1.84), (375.7, 1.960, 1.88), (393.6, 1.960, 1.89),
           (413.2, 1.950, 1.86), (442.8, 1.826, 1.81), (476.8, 1.541, 1.71), (516.6, 0.878, 2.01),
           (563.5, 0.613, 2.64), (619.9, 0.487, 3.31), (826.5, 0.418, 5.13)),
    "Ag": ((344.4, 0.230, 1.13), (354.2, 0.211, 1.42), (381.5, 0.229, 1.86), (413.3, 0.226, 2.28),
           (495.9, 0.237, 3.09), (619.9, 0.269, 4.18), (826.6, 0.271, 5.80)),
    "Cu": ((344.4, 1.310, 1.87), (364.7, 1.270, 1.95), (387.5, 1.232, 2.07), (413.3, 1.184, 2.21),
           (442.8, 1.169, 2.36), (476.9, 1.152, 2.50), (516.6, 1.121, 2.60), (539.1, 1.037, 2.59),
           (563.6, 0.826, 2.60), (590.4, 0.468, 2.81), (619.9, 0.272, 3.24), (652.5, 0.214, 3.67),
           (670.2, 0.215, 3.86)),
    "Al": ((310.0, 0.298, 3.70), (413.3, 0.548, 5.00), (495.9, 0.771, 5.91), (619.9, 1.292, 7.28),
           (688.8, 1.731, 7.96), (729.3, 2.082, 8.34), (774.9, 2.588, 8.55), (826.6, 2.829, 7.75)),
}
MATERIALS = tuple(TABLES)
#: (η, k) in linear sRGB of each metal: :func:`spectrum_to_rgb` of :data:`TABLES` (stored, so that rendering does not
#: import colour-science; ``tests/test_ggx_conductor.py`` recomputes them).
METALS_RGB: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "Au": ((0.37824656946309154, 0.7141140015095376, 1.841622628673691),
           (3.6685884678515177, 2.3370206248644445, 1.6953715220157284)),
    "Ag": ((0.2740929757585342, 0.24924648179240788, 0.2284982335746736),
           (4.410493281277804, 3.5221331178717428, 2.5373905056495336)),
    "Cu": ((0.07476382678048132, 0.9637844513209584, 1.2087074311760457),
           (3.335196287950483, 2.59691961834041, 2.3533136644141694)),
    "Al": ((1.4348099870012005, 0.9666037996243937, 0.6051447392197153),
           (7.574060935733609, 6.447590516297282, 5.2805904904796925)),
}
_LAMBDA = np.arange(380.0, 781.0, 5.0)


@functools.cache
def _spectrum_to_rgb_matrix() -> np.ndarray:
    """(3, L) weights: linear sRGB of a spectrum sampled at :data:`_LAMBDA` (module docstring)."""
    opts = np.get_printoptions()
    import colour  # it sets NumPy's legacy print options on import: restored below

    np.set_printoptions(**opts)
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    xyz_bar = np.stack([np.interp(_LAMBDA, cmfs.wavelengths, cmfs.values[:, j]) for j in range(3)])
    xyz_bar = xyz_bar / xyz_bar[1].sum()  # a constant spectrum c → Y = c
    cs = colour.RGB_COLOURSPACES["sRGB"]
    white_e = colour.XYZ_to_xy(xyz_bar.sum(axis=1))
    adapt = colour.adaptation.matrix_chromatic_adaptation_VonKries(
        colour.xy_to_XYZ(white_e), colour.xy_to_XYZ(cs.whitepoint), transform="Bradford")
    m = cs.matrix_XYZ_to_RGB @ adapt @ xyz_bar
    return m / m.sum(axis=1, keepdims=True)  # exact grey for constants (removes the tables' rounding)


def spectrum_to_rgb(wavelengths, values) -> np.ndarray:
    """Linear sRGB (3,) of a spectrum given at ``wavelengths`` (nm), by the module docstring's conversion.

    Examples
    --------
    >>> import numpy as np
    >>> np.round(spectrum_to_rgb([400.0, 700.0], [2.0, 2.0]), 12).tolist()   # a constant stays grey
    [2.0, 2.0, 2.0]
    """
    s = np.interp(_LAMBDA, np.asarray(wavelengths, float), np.asarray(values, float))
    return _spectrum_to_rgb_matrix() @ s


def convert_table(name: str) -> tuple[np.ndarray, np.ndarray]:
    """(η, k) of metal ``name`` converted from :data:`TABLES` now (what :data:`METALS_RGB` stores)."""
    t = np.array(TABLES[name])
    return spectrum_to_rgb(t[:, 0], t[:, 1]), spectrum_to_rgb(t[:, 0], t[:, 2])


def metal_eta_k(name: str) -> tuple[np.ndarray, np.ndarray]:
    """(η, k) as linear-sRGB triples of metal ``name`` (one of :data:`MATERIALS`); KeyError for others.

    Examples
    --------
    >>> eta, k = metal_eta_k("Au")
    >>> bool(eta[0] < eta[2])        # gold: low η in the red, high in the blue
    True
    """
    eta, k = METALS_RGB[name]
    return np.array(eta), np.array(k)

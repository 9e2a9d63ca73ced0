"""``measured`` BSDF: an isotropic BRDF tabulated on MERL's half/difference grid, importance-sampled from the table.

==============  ======  =======  ==============================================================================
parameter       tag     default  meaning
==============  ======  =======  ==============================================================================
``filename``    string  —        a MERL ``.binary`` file (resolved from the scene's folder), or ``table=`` in
                                 Python: an array (90, 90, 180, 3) of f in the layout below
==============  ======  =======  ==============================================================================

**The MERL format** (Matusik et al. 2003, "A Data-Driven Reflectance Model"; the MERL BRDF database's
reader): three int32 dimensions (90, 90, 180) = (n_θh, n_θd, n_φd), then 3·90·90·180 float64 values, all of
red, then green, then blue, each channel indexed ``(i_θh·90 + i_θd)·180 + i_φd`` and multiplied by the
scale factors 1/1500, 1.15/1500, 1.66/1500. Negative entries (unmeasured) count as 0. The indices are

    i_θh = 90·sqrt(θh/(π/2)),   i_θd = 90·θd/(π/2),   i_φd = 180·φd/π  (φd folded into [0, π)),

with (θh, θd, φd) Rusinkiewicz's half/difference angles of (ω_i, ω_o) (:func:`brdflab.viz.coords.io_to_half_diff`;
φd and φd + π are the same by reciprocity). MERL's own reader truncates the indices (nearest lower node);
brdflab interpolates **trilinearly** between the nodes (node i at the index coordinate i; beyond the last
node of θh or θd the last value is held; φd wraps with period π), so a table made from a smooth model
(:func:`tabulate`) renders like the model.

**Sampling.** For 24 incident angles θ_k (uniform in θ, 0°…90°) a density over the half vector is
tabulated on 64 × 96 cells in (u, φ_h), θ_h = u²·π/2 (the sqrt grading of MERL's θh axis: fine cells at the
specular peak), from node values of the half-vector density Y(f) cos θ_o · 4|ω_i·ω_h| (dω_o = 4|ω_i·ω_h|
dω_h, PBR 4th ed. eq. 9.33); a cell weighs the mean of its corners times its solid angle. A sample picks
the table of the neighbouring θ_k below or above θ_i with the linear weights (the third uniform), a cell
from it (:class:`~brdflab.math.distribution.Distribution2DStack`), then ω_h inside the cell from the
bilinear density in (φ_h, cos θ_h) between the cell's four node values (so the density is continuous from
cell to cell: no step for a quadrature to trip on), and ω_o = reflect(ω_i, ω_h); a defensive share δ = 0.1
of cosine-weighted samples keeps pdf > 0 wherever f > 0. The pdf is the same mixture, evaluated exactly:
p(ω_o) = (1−δ) Σ_k w_k p_k(ω_h)/(4|ω_i·ω_h|) + δ cos θ_o/π — finite everywhere, also at the specular peak.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from brdflab.bsdf.base import BSDF, BSDFSample, cos_weight
from brdflab.errors import BrdflabError
from brdflab.math import warps
from brdflab.math.distribution import Distribution2DStack
from brdflab.scene.properties import PropertyList
from brdflab.viz import coords

#: MERL's table dimensions (θh, θd, φd) and per-channel scale factors.
N_TH, N_TD, N_PD = 90, 90, 180
SCALE = np.array([1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0])
#: Luminance weights (Rec. 709) for the sampling density.
LUM = np.array([0.2126, 0.7152, 0.0722])
#: Sampling tables: incident angles, cells in u = sqrt(θh/(π/2)) and in φ_h, defensive cosine share.
N_THETA_I, N_U, N_PHI, DEFENSIVE = 24, 64, 96, 0.1
HEADER = np.array([N_TH, N_TD, N_PD], dtype="<i4")


def read_merl(path: str | Path, raw: bool = False) -> np.ndarray:
    """The BRDF of a MERL ``.binary`` file as an array (90, 90, 180, 3) of f (scaled; negative → 0).

    ``raw``: the values as stored (scaled), negative and non-finite ones included (MERL marks nodes without a
    measurement with negative values; :func:`brdflab.fitting.fit` leaves such nodes out instead of fitting 0).

    Raises
    ------
    BrdflabError
        Not a regular file, over the input limit, wrong dimensions or a size that does not match them (the
        size is checked before the file is read).
    """
    from brdflab.limits import check_input, read_input

    expected = HEADER.nbytes + 3 * N_TH * N_TD * N_PD * 8
    if check_input(path, "MERL BRDF file") < HEADER.nbytes:
        raise BrdflabError("MERL BRDF file is too short for its header", path)
    with open(path, "rb") as f:  # the header says what is wrong before the rest is read
        dims = np.frombuffer(f.read(HEADER.nbytes), dtype="<i4")
    if len(dims) == len(HEADER) and not np.array_equal(dims, HEADER):
        raise BrdflabError(f"MERL BRDF file has dimensions {tuple(int(d) for d in dims)}, expected (90, 90, 180)",
                           path)
    data = read_input(path, "MERL BRDF file (90×90×180×3 doubles)", size=expected)
    v = np.frombuffer(data[HEADER.nbytes:], dtype="<f8").reshape(3, N_TH, N_TD, N_PD)
    table = np.moveaxis(v, 0, -1) * SCALE
    return table if raw else measured_values(table)


def measured_values(table: np.ndarray) -> np.ndarray:
    """A raw table with its unmeasured nodes (negative, NaN, infinite) set to 0, as rendering needs it."""
    with np.errstate(invalid="ignore"):
        return np.where(np.isfinite(table) & (table > 0), table, 0.0)


def write_merl(path: str | Path, table: np.ndarray) -> None:
    """Write an array (90, 90, 180, 3) of f as a MERL ``.binary`` file (the inverse of :func:`read_merl`)."""
    t = np.asarray(table, dtype=np.float64)
    if t.shape != (N_TH, N_TD, N_PD, 3):
        raise BrdflabError(f"a MERL table has shape (90, 90, 180, 3), got {t.shape}")
    values = np.moveaxis(t / SCALE, -1, 0).astype("<f8")
    with open(path, "wb") as f:
        f.write(HEADER.tobytes())
        f.write(values.tobytes())


def node_angles() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(θh, θd, φd) of the table's nodes (radians), each 1-D."""
    th = (np.arange(N_TH) / N_TH) ** 2 * (np.pi / 2)
    td = np.arange(N_TD) / N_TD * (np.pi / 2)
    pd = np.arange(N_PD) / N_PD * np.pi
    return th, td, pd


def tabulate(bsdf) -> np.ndarray:
    """The table (90, 90, 180, 3) of any isotropic BSDF's f at the nodes (for tests, ``fit`` and conversions)."""
    th, td, pd = node_angles()
    TH, TD, PD = np.meshgrid(th, td, pd, indexing="ij")
    wi, wo = coords.half_diff_to_io(TH, 0.0, TD, PD)
    f = np.zeros((wi.shape[0], 3))
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    f[ok] = np.asarray(bsdf.eval(np.ascontiguousarray(wi[ok]), np.ascontiguousarray(wo[ok])), dtype=np.float64)
    return f.reshape(N_TH, N_TD, N_PD, 3)


def table_coordinates(wi: np.ndarray, wo: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Continuous index coordinates (x_θh, x_θd, x_φd) of direction pairs (module docstring).

    The difference vector d = R_y(−θh) R_z(−φh) ω_i (:mod:`brdflab.viz.coords`) written out with the half
    vector's own cosines and sines (no angle of φh is needed): with (p, q) = ω_i's components along and across
    ω_h's azimuth, d = (cos θh p − sin θh ω_i.z, q, sin θh p + cos θh ω_i.z).
    """
    h = wi + wo
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    sin_h = np.hypot(h[:, 0], h[:, 1])
    pole = sin_h < 1e-12
    safe = np.where(pole, 1.0, sin_h)
    cphi, sphi = np.where(pole, 1.0, h[:, 0] / safe), np.where(pole, 0.0, h[:, 1] / safe)
    p = cphi * wi[:, 0] + sphi * wi[:, 1]
    q = cphi * wi[:, 1] - sphi * wi[:, 0]
    cos_h = h[:, 2]
    dx = cos_h * p - sin_h * wi[:, 2]
    dz = sin_h * p + cos_h * wi[:, 2]
    theta_h = np.arctan2(sin_h, cos_h)
    theta_d = np.arccos(np.clip(dz, -1.0, 1.0))
    x_th = np.sqrt(np.clip(theta_h / (np.pi / 2), 0.0, 1.0)) * N_TH
    x_td = np.clip(theta_d / (np.pi / 2), 0.0, 1.0) * N_TD
    x_pd = np.mod(np.arctan2(q, dx), np.pi) / np.pi * N_PD
    return x_th, x_td, x_pd


class Measured(BSDF):
    """An isotropic tabulated BRDF (MERL layout), trilinearly interpolated and importance-sampled."""

    type_name = "measured"
    KNOWN = {"filename": "string"}

    def __init__(self, filename: str = "", table: np.ndarray | None = None) -> None:
        if table is None:
            if not filename:
                raise BrdflabError("measured: give a MERL .binary filename (or table= in Python)")
            table = read_merl(filename)
        t = np.asarray(table, dtype=np.float64)
        if t.shape != (N_TH, N_TD, N_PD, 3):
            raise BrdflabError(f"measured: a table has shape (90, 90, 180, 3), got {t.shape}")
        if not np.all(np.isfinite(t)) or np.any(t < 0):
            raise BrdflabError("measured: the table has negative or non-finite values")
        self.filename = str(filename)
        #: Files the material was read from (the loader counts them among the run's inputs).
        self.input_files: tuple[Path, ...] = (Path(filename),) if filename else ()
        self.table = t
        self._padded = self._pad(t)
        self._build_sampling()

    @classmethod
    def from_properties(cls, props: PropertyList) -> Measured:
        """Build from ``<bsdf type="measured"><string name="filename" value="…"/></bsdf>``."""
        from brdflab.scene.loader import resolve_path

        props.check_known(cls.KNOWN)
        name = props.get_string("filename")
        # found as the loader finds meshes and maps: the scene's folder, then the working directory
        path = resolve_path(Path(props.file).parent if props.file else Path.cwd(), name) or Path(name)
        try:
            bsdf = cls(str(path))
        except BrdflabError as exc:
            raise props.error("filename", f"{exc.message} ({path})") from None
        return bsdf

    # -- evaluation -----------------------------------------------------------------------------------
    def _lookup(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """Trilinear interpolation in the padded table (:meth:`_pad`): eight gathers at fixed offsets."""
        x_th, x_td, x_pd = table_coordinates(wi, wo)
        x_th = np.minimum(x_th, N_TH - 1)
        x_td = np.minimum(x_td, N_TD - 1)
        i = np.floor(x_th).astype(np.int64)
        j = np.floor(x_td).astype(np.int64)
        m = np.minimum(np.floor(x_pd).astype(np.int64), N_PD - 1)
        a, b, c = x_th - i, x_td - j, x_pd - m
        base = (i * (N_TD + 1) + j) * (N_PD + 1) + m
        s_pd, s_td, s_th = 1, N_PD + 1, (N_TD + 1) * (N_PD + 1)
        out = np.zeros((len(wi), 3))
        for off, w in ((0, (1 - a) * (1 - b) * (1 - c)), (s_pd, (1 - a) * (1 - b) * c),
                       (s_td, (1 - a) * b * (1 - c)), (s_td + s_pd, (1 - a) * b * c),
                       (s_th, a * (1 - b) * (1 - c)), (s_th + s_pd, a * (1 - b) * c),
                       (s_th + s_td, a * b * (1 - c)), (s_th + s_td + s_pd, a * b * c)):
            out += w[:, None] * np.take(self._padded, base + off, axis=0)
        return out

    @staticmethod
    def _pad(t: np.ndarray) -> np.ndarray:
        """The table with one more node on each axis — θh and θd hold their last node, φd wraps (period π) —
        flattened to (91·91·181, 3), so that every corner of a cell is at a fixed offset."""
        p = np.concatenate([t, t[:, :, :1]], axis=2)
        p = np.concatenate([p, p[:, -1:]], axis=1)
        p = np.concatenate([p, p[-1:]], axis=0)
        return np.ascontiguousarray(p.reshape(-1, 3))

    def eval(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """f(ω_i, ω_o) interpolated from the table; 0 unless both directions are above the surface."""
        ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
        out = np.zeros((len(wi), 3))
        if ok.any():
            out[ok] = self._lookup(wi[ok], wo[ok])
        return out

    # -- sampling ---------------------------------------------------------------------------------------
    @staticmethod
    def _row_cos(rows: np.ndarray) -> np.ndarray:
        """cos θh of node rows (θh = u²·π/2 at u = row/N_U)."""
        return np.cos((np.asarray(rows, dtype=np.float64) / N_U) ** 2 * (np.pi / 2))

    def _build_sampling(self) -> None:
        thetas = np.linspace(0.0, np.pi / 2, N_THETA_I)
        rows, cols = np.meshgrid(np.arange(N_U + 1), np.arange(N_PHI), indexing="ij")
        h = coords.spherical(np.arccos(self._row_cos(rows.ravel())), cols.ravel() / N_PHI * 2 * np.pi)
        nodes = np.zeros((N_THETA_I, N_U + 1, N_PHI + 1))
        for k, t in enumerate(thetas):
            wi = np.tile(coords.spherical(min(t, np.radians(89.9)), 0.0), (len(h), 1))
            cos_d = np.sum(wi * h, axis=1)
            wo = 2.0 * cos_d[:, None] * h - wi
            # density of half vectors ∝ Y(f) cos θo · 4|ω_i·ω_h| (dω_o = 4|ω_i·ω_h| dω_h)
            g = self.eval(wi, wo) @ LUM * np.maximum(wo[:, 2], 0.0) * 4.0 * np.abs(cos_d)
            nodes[k, :, :N_PHI] = g.reshape(N_U + 1, N_PHI)
        nodes[:, :, N_PHI] = nodes[:, :, 0]  # φ is periodic
        nodes[:, 0, :] = nodes[:, 0, :].mean(axis=1, keepdims=True)  # the pole: one direction
        c = self._row_cos(np.arange(N_U + 1))
        solid = (c[:-1] - c[1:])[:, None] * (2 * np.pi / N_PHI)
        corners = 0.25 * (nodes[:, :-1, :-1] + nodes[:, 1:, :-1] + nodes[:, :-1, 1:] + nodes[:, 1:, 1:])
        self._nodes = nodes
        self._solid = solid
        self._dist = Distribution2DStack(corners * solid)

    def _table_choice(self, wi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lower table index k and the weight t of table k + 1 for each ω_i."""
        x = np.arccos(np.clip(wi[:, 2], -1.0, 1.0)) / (np.pi / 2) * (N_THETA_I - 1)
        k = np.clip(np.floor(x).astype(np.int64), 0, N_THETA_I - 2)
        return k, np.clip(x - k, 0.0, 1.0)

    def _corners(self, k: np.ndarray, row: np.ndarray, col: np.ndarray) -> tuple[np.ndarray, ...]:
        """Node values (v00, v10, v01, v11) of cells: first index along φ (s), second along cos θh (t)."""
        n = self._nodes
        return n[k, row, col], n[k, row, col + 1], n[k, row + 1, col], n[k, row + 1, col + 1]

    def sample(self, wi: np.ndarray, u: np.ndarray, uv: np.ndarray | None = None) -> BSDFSample:
        """Table sample (module docstring); ``u[:, 2]`` picks the defensive share and the θ_i table."""
        k, t = self._table_choice(wi)
        cosine = u[:, 2] < DEFENSIVE
        rest = np.clip((u[:, 2] - DEFENSIVE) / (1.0 - DEFENSIVE), 0.0, 1.0)
        kk = np.where(rest < t, k + 1, k)
        pts, _ = self._dist.sample(kk, u[:, :2])
        col = np.minimum(np.floor(pts[:, 0]).astype(np.int64), N_PHI - 1)
        row = np.minimum(np.floor(pts[:, 1]).astype(np.int64), N_U - 1)
        v00, v10, v01, v11 = self._corners(kk, row, col)
        # the bilinear density inside the cell: s (φ) from its linear marginal, then t (cos θh) given s
        sf = _sample_linear(v00 + v01, v10 + v11, pts[:, 0] - col)
        tf = _sample_linear((1 - sf) * v00 + sf * v10, (1 - sf) * v01 + sf * v11, pts[:, 1] - row)
        c = self._row_cos(row)
        cos_h = c - tf * (c - self._row_cos(row + 1))
        phi = (col + sf) / N_PHI * 2 * np.pi + np.arctan2(wi[:, 1], wi[:, 0])
        h = coords.spherical(np.arccos(np.clip(cos_h, -1.0, 1.0)), phi)
        wo = 2.0 * np.sum(wi * h, axis=1)[:, None] * h - wi
        wo[cosine] = warps.square_to_cosine_hemisphere(u[cosine, :2])
        wo /= np.linalg.norm(wo, axis=1, keepdims=True)
        pdf = np.where((wo[:, 2] <= 0) | (wi[:, 2] <= 0), 0.0, self.pdf(wi, wo))
        return BSDFSample(wo, cos_weight(self.eval(wi, wo), wo, pdf), pdf)

    def _table_pdf(self, k: np.ndarray, col: np.ndarray, row: np.ndarray, s: np.ndarray, t: np.ndarray):
        """Density of half vectors (per solid angle) of table k at cell (row, col), position (s, t) in it."""
        v00, v10, v01, v11 = self._corners(k, row, col)
        mean = 0.25 * (v00 + v10 + v01 + v11)
        b = (1 - s) * (1 - t) * v00 + s * (1 - t) * v10 + (1 - s) * t * v01 + s * t * v11
        prob = np.take(self._dist._flat, k * self._dist.cells + row * N_PHI + col)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(mean > 0, prob / self._solid[row, 0] * b / mean, 0.0)

    def pdf(self, wi: np.ndarray, wo: np.ndarray, uv: np.ndarray | None = None) -> np.ndarray:
        """The density of :meth:`sample` (solid angle), exactly: the θ_i-table mixture plus the cosine share.

        Inside a cell the half-vector density is bilinear in (φ_h, cos θh) between the node values, so it is
        continuous; p(ω_o) = p_h/(4|ω_i·ω_h|).
        """
        ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
        out = np.zeros(len(wi))
        if not ok.any():
            return out
        a, b = wi[ok], wo[ok]
        h = a + b
        h /= np.linalg.norm(h, axis=1, keepdims=True)
        cos_h = np.clip(h[:, 2], -1.0, 1.0)
        x = np.mod(np.arctan2(h[:, 1], h[:, 0]) - np.arctan2(a[:, 1], a[:, 0]), 2 * np.pi) / (2 * np.pi) * N_PHI
        y = np.sqrt(np.arccos(cos_h) / (np.pi / 2)) * N_U
        col = np.clip(np.floor(x).astype(np.int64), 0, N_PHI - 1)
        row = np.clip(np.floor(y).astype(np.int64), 0, N_U - 1)
        c0, c1 = self._row_cos(row), self._row_cos(row + 1)
        s = np.clip(x - col, 0.0, 1.0)
        t = np.clip((c0 - cos_h) / (c0 - c1), 0.0, 1.0)
        k, w = self._table_choice(a)
        p_h = (1.0 - w) * self._table_pdf(k, col, row, s, t) + w * self._table_pdf(k + 1, col, row, s, t)
        cos_d = np.abs(np.sum(a * h, axis=1))
        with np.errstate(divide="ignore", invalid="ignore"):
            p_table = np.where(cos_d > 0, p_h / (4.0 * cos_d), 0.0)
        out[ok] = (1.0 - DEFENSIVE) * p_table + DEFENSIVE * b[:, 2] / np.pi
        return out


def _sample_linear(a: np.ndarray, b: np.ndarray, xi: np.ndarray) -> np.ndarray:
    """x ∈ [0, 1] with density ∝ (1 − x)·a + x·b (a, b ≥ 0) for uniforms ``xi``: the root of
    a x + (b − a) x²/2 = ξ (a + b)/2 (PBR 4th ed. §A.4.3's linear sampling)."""
    xi = np.clip(xi, 0.0, 1.0)
    d = b - a
    with np.errstate(divide="ignore", invalid="ignore"):
        root = np.sqrt(np.maximum(a * a + d * (a + b) * xi, 0.0))
        x = np.where(np.abs(d) > 1e-12 * (a + b), (root - a) / d, xi)
        x = np.where((a + b) > 0, x, xi)
    return np.clip(x, 0.0, 1.0)

"""Users' own light samples against brdflab's emitters (``brdflab chi2 --samples FILE --against-emitter
scene.xml[:index]``): the emitter-sampling counterpart of :mod:`brdflab.judges.samples.bsdf_checks`.

File format
-----------
The conventions of :func:`brdflab.judges.samples.bsdf_checks.read_table` (text with ``#`` comments, ``.npy``, or
``.npz`` with the key ``samples``); one row per call of the light sampler, in world space:

==========================================================  ==================================================
columns                                                     meaning
==========================================================  ==================================================
``x_x x_y x_z``                                             the reference (shading) point the light is sampled from
``y_x y_y y_z``                                             the sampled point on the light
``n_x n_y n_z``                                             the light's normal at y
``pdf``                                                     the sampler's density of y
``measure``                                                 0: ``pdf`` is per unit area (p_A), 1: per steradian (p_ω)
``L_r L_g L_b`` (optional)                                  the radiance the sample returns (arriving at x)
==========================================================  ==================================================

11 or 14 columns. Without ``:index`` the samples are of the scene's whole light (an emitter chosen by the
scene's selection, uniform as in Nori, then a point on it) and the pdf includes the selection probability;
with ``:index`` (0-based, in the scene's order of ``<emitter>`` elements) they are of that emitter alone.
A sampler call that produced no point is a row with pdf 0 and y = 0 0 0.

What is checked
---------------
1. **On the emitter**: every y lies on the light (distance to its nearest triangle ≤ :data:`ON_RTOL` × the
   light's size; a point light's position), and the normal column agrees with brdflab's shading normal there.
2. **Self-consistency** (the verdict for area lights, whatever method drew the points): the points against
   *their own* pdf column — Σ 1_c(y)/p_A(y)/N must estimate each cell's area
   (:func:`~brdflab.judges.samples.light_checks._self_consistency_check`).
   When it holds, the two comparisons with brdflab's own method below (pdf and distribution) are reported as
   information ("a different sampling method than brdflab's (self-consistent)"), not as failures: a correct
   sampler of another method passes. When it fails, their hints name the likely bug.
3. **pdf** (against brdflab's method): brdflab samples area lights uniformly by area, p_A = p_sel / A_e; in
   solid angle p_ω = p_A · r² / |cos θ_y| (r = ‖y − x‖, θ_y between the light's normal and y → x; spec §13.2.3). The
   file's pdf, in its measure, must agree within 1 % for all but 0.1 % of the front-facing samples. A
   mismatch is explained, where one fits, by the usual bugs: area measure flagged as solid angle (missing
   r²/cos), the reverse, a missing cos θ_y or r², a missing or doubled selection probability, a triangle's pdf
   1/A_k (or 1/(K·A_k), triangles chosen uniformly) instead of the emitter's.
4. **Distribution** (against brdflab's method): Pearson's chi-square of the points on the light over n²
   congruent sub-triangles of every triangle (:func:`brdflab.judges.lights.samplers.subtriangle_cell`), expected
   counts N · p_sel · A_k / (A_e n²)
   (:data:`brdflab.judges.material.chi2.SIGNIFICANCE`, cells below 5 expected pooled); a failure is explained by
   sub-tests: emitter frequencies against the scene's selection, triangle counts against a *uniform* choice
   of triangles (fits where the area-weighted one does not), points within their triangles.
5. **Radiance** (14 columns, constant-radiance lights): L_e where y faces x, else 0 (one-sided emitters);
   I/r² for a point light.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from brdflab.errors import BrdflabError, ascii_int
from brdflab.judges.lights.samplers import shading_normals
from brdflab.judges.material import chi2 as c2
from brdflab.judges.samples.bsdf_checks import read_table
from brdflab.judges.samples.light_checks import (  # noqa: F401 (re-exported: the module's former contents)
    MIN_SAMPLES,
    NORMAL_DOT,
    ON_RTOL,
    POOL,
    Check,
    EmitterSamples,
    _distribution_check,
    _geometry,
    _Light,
    _pdf_check,
    _pearson,
    _radiance_check,
    _self_consistency_check,
    nearest_triangle,
)

ALLOWED = (11, 14)
EXPECTED = "11 or 14 columns (x y n pdf measure [L_r L_g L_b]: reference point, light point, its normal, pdf, " \
           "0 = area / 1 = solid angle measure, radiance)"
def read_emitter_samples(path: str | Path) -> EmitterSamples:
    """Read an emitter-samples file; :class:`BrdflabError` with ``file:line`` if it is malformed.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "l.txt"
    >>> _ = p.write_text("# x y n pdf measure\\n0 0 0  0 1 0  0 -1 0  0.25 0\\n")
    >>> s = read_emitter_samples(p)
    >>> s.y.tolist(), s.solid_angle.tolist()
    ([[0.0, 1.0, 0.0]], [False])
    """
    data, lines, ncol = read_table(path, ALLOWED, EXPECTED)
    m = data[:, 10]
    bad = (m != 0) & (m != 1)
    if bad.any():
        i = int(np.argmax(bad))
        raise BrdflabError(f"measure column (11th) is {m[i]:g}; expected 0 (area) or 1 (solid angle)", file=path,
                           line=int(lines[i]))
    neg = data[:, 9] < 0
    if neg.any():
        i = int(np.argmax(neg))
        raise BrdflabError(f"negative pdf {data[i, 9]:g}", file=path, line=int(lines[i]))
    return EmitterSamples(str(path), data[:, 0:3], data[:, 3:6], data[:, 6:9], data[:, 9], m == 1,
                          data[:, 11:14] if ncol == 14 else None, lines)


def parse_target(text: str) -> tuple[Path, int | None]:
    """``scene.xml:2`` → (scene.xml, 2); ``scene.xml`` → (scene.xml, None)."""
    head, sep, tail = text.rpartition(":")
    index = ascii_int(tail) if sep and head else None
    if index is not None:
        return Path(head), index
    return Path(text), None


@dataclass
class EmitterSamplesResult:
    """All checks of a file against an emitter (or the whole light) of a scene."""

    path: str
    target: str
    samples: int
    checks: list[Check]

    @property
    def passed(self) -> bool:
        """True when every check passed."""
        return all(c.passed for c in self.checks)

    def messages(self) -> list[str]:
        """One line per check (and its hint)."""
        out = []
        for c in self.checks:
            out.append(f"  {'ok  ' if c.passed else 'FAIL'} {c.name}: {c.summary}")
            if c.hint:
                out.append(f"       hint: {c.hint}")
        return out

    def to_dict(self) -> dict:
        """Plain form (JSON)."""
        return {"path": self.path, "target": self.target, "samples": self.samples, "passed": self.passed,
                "checks": [{"name": c.name, "passed": c.passed, "summary": c.summary, "hint": c.hint, **c.data}
                           for c in self.checks]}


def check_emitter_samples(samples: str | Path | EmitterSamples, scene, index: int | None = None,
                          threshold: float = c2.SIGNIFICANCE, target: str = "") -> EmitterSamplesResult:
    """Check a file of light samples against emitter ``index`` of ``scene`` (a loaded scene or a path), or
    against the scene's whole light when ``index`` is None (see the module docstring)."""
    from brdflab.scene.loader import load_scene

    s = samples if isinstance(samples, EmitterSamples) else read_emitter_samples(samples)
    if not hasattr(scene, "emitters"):
        target = target or str(scene) + ("" if index is None else f":{index}")
        scene = load_scene(scene)
    light = _Light(scene, index)
    target = target or ("the scene's light" if index is None else f"emitter {index}")
    n = len(s.pdf)
    nothing = (s.pdf == 0) & np.all(s.y == 0, axis=1)
    got = np.flatnonzero(~nothing)
    checks = []
    # 1. On the emitter: owner j (index into light.emitters), triangle, barycentrics, brdflab's normal.
    tol = ON_RTOL * light.size
    owner = np.full(n, -1)
    tri = np.full(n, -1)
    dist = np.full(n, np.inf)
    bary = np.zeros((n, 2))
    if len(light.tris) and len(got):
        k, d, b = nearest_triangle(s.y[got], light.tris, far=tol)
        dist[got], tri[got], bary[got] = d, k, b
        owner[got] = np.where(d <= tol, light.owner[k], -1)
    for j, e in enumerate(light.emitters):
        if e.is_delta and len(got):
            dp = np.linalg.norm(s.y[got] - e.position, axis=1)
            closer = dp < dist[got]
            dist[got] = np.where(closer, dp, dist[got])
            owner[got] = np.where(closer & (dp <= tol), j, owner[got])
            tri[got] = np.where(closer, -1, tri[got])
    on = owner >= 0
    off = (~on) & (~nothing)
    summary = f"{int(on.sum())} of {len(got)} sampled points on {target}"
    hint = ""
    if off.any():
        i = int(np.flatnonzero(off)[np.argmax(dist[off])])
        summary += (f"; {int(off.sum())} off it (up to {dist[i]:.3g} away, line {int(s.lines[i])}; tolerance "
                    f"{tol:.2g})")
        hint = ("points near the light's plane but outside its triangles: check the square-to-triangle warp "
                "(b = (1 − √u₁, u₂ √u₁)) and the vertices used" if np.median(dist[off]) < 0.05 * light.size
                else "points far from this light: wrong emitter (index?), or a transform left out")
    if nothing.any():
        summary += f"; {int(nothing.sum())} call(s) produced no point"
    checks.append(Check("points on the emitter", not off.any() and on.any(), summary, hint,
                        {"on": int(on.sum()), "off": int(off.sum()), "no_point": int(nothing.sum())}))
    # brdflab's shading normal at each point on an area light.
    ns = np.zeros((n, 3))
    area_pts = on & (tri >= 0)
    for j, e in enumerate(light.emitters):
        mine = np.flatnonzero(area_pts & (owner == j))
        if len(mine):
            ns[mine] = shading_normals(e, light.local[tri[mine]], bary[mine])
    if area_pts.any():
        nf = s.n[area_pts]
        ln = np.linalg.norm(nf, axis=1)
        dot = np.sum(nf * ns[area_pts], axis=1) / np.where(ln > 0, ln, 1.0)
        bad = (dot < NORMAL_DOT) | (ln == 0)
        nhint = ""
        if bad.any() and np.median(dot[bad]) < -NORMAL_DOT:
            nhint = "the normals point the other way (to the back of the light): a flipped cross product?"
        elif bad.any() and np.all(np.abs(np.abs(dot[bad]) - 1) > 1e-3):
            nhint = ("normals differ from the light's interpolated shading normal (or face normal where the mesh "
                     "has no vertex normals)")
        checks.append(Check("normals", not bad.any(), f"{int((~bad).sum())} of {len(dot)} agree with brdflab's "
                            f"(within {np.degrees(np.arccos(NORMAL_DOT)):.1f}°)", nhint))
    # 2. and 3.: the samples against their own pdf (the verdict), and against brdflab's method (pdf, distribution).
    own = _self_consistency_check(s, light, owner, tri, bary, ns, on, threshold)
    same = [_pdf_check(s, light, owner, tri, ns, on), _distribution_check(s, light, owner, tri, bary, on, threshold)]
    if own is not None:
        checks.append(own)
        if own.passed:  # a correct sampler of another method: brdflab's pdf and distribution are information only
            for c in same:
                if not c.passed:
                    c.summary += " — a different sampling method than brdflab's (self-consistent), not an error"
                    c.passed, c.hint, c.data["informational"] = True, "", True
    checks += same
    # 4. radiance.
    if s.radiance is not None:
        rc = _radiance_check(s, light, owner, ns, on)
        if rc is not None:
            checks.append(rc)
    return EmitterSamplesResult(s.path, target, n, checks)


def own_samples(scene, index: int | None, n: int, seed: int = 0) -> np.ndarray:
    """(N, 14) brdflab's own light samples in the file format (solid-angle pdf, measure 1), from shading
    points of the scene: what a correct sampler writes (tests, examples)."""
    from brdflab.integrator.common import choose_emitters
    from brdflab.judges.lights.samplers import reference_points

    p, _ = reference_points(scene, seed=seed)
    rng = np.random.default_rng(seed + 1)
    x = p[rng.integers(0, len(p), n)]
    if index is None:
        e_of = choose_emitters(scene, rng.random(n))
        p_sel = np.asarray(scene.emitter_pmf)[e_of]
    else:
        e_of, p_sel = np.full(n, index), np.ones(n)
    out = np.zeros((n, 14))
    out[:, 0:3] = x
    out[:, 10] = 1.0
    u = rng.random((n, 3))
    light = _Light(scene, index)
    for e in np.unique(e_of):
        sel = np.flatnonzero(e_of == e)
        em = scene.emitters[e]
        r = em.sample(x[sel], u[sel])
        y = x[sel] + r.wi * np.where(np.isfinite(r.dist), r.dist, 0.0)[:, None]
        out[sel, 3:6] = y
        out[sel, 9] = r.pdf * p_sel[sel]
        out[sel, 11:14] = r.radiance
        if not em.is_delta:
            k, _, b = nearest_triangle(y, light.tris)
            j = light.ids.index(int(e))
            out[sel, 6:9] = shading_normals(em, light.local[k], b) if np.all(light.owner[k] == j) else 0.0
    return out


#: The files :func:`write_emitter_report` writes (checked by :func:`brdflab.outputs.prepare_folder`).
EMITTER_REPORT_FILES = ("emitter_samples.html", "emitter_samples.json")


def write_emitter_report(res: EmitterSamplesResult, out: Path) -> Path:
    """Write ``emitter_samples.json`` and ``emitter_samples.html`` into ``out``; return the page path."""
    from brdflab.outputs import json_text, write_text
    from brdflab.pages import page as html

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    write_text(out / "emitter_samples.json", json_text(res.to_dict(), indent=2))
    rows = [[c.name, "passed" if c.passed else "FAILED", c.summary, c.hint] for c in res.checks]
    body = html.section("Verdict", html.esc_p(f"{res.path}: {res.samples} light samples against {res.target}: "
                                              + ("all checks passed" if res.passed else "FAILED"))
                        + html.table(["check", "result", "measured", "hint"], rows))
    body += html.section("Method", html.esc_p("See docs/external-samples.md (light samples) and "
                                              "brdflab/judges/samples/light_samples.py."))
    page = html.page(f"brdflab light samples — {Path(res.path).name}", body)
    path = out / "emitter_samples.html"
    write_text(path, page)
    return path

"""Mutation testing of the model and light-transport code (a benchmark, not part of CI).

Run from the repository root (CPU-heavy: a bounded, reproducible sample of the mutants by default)::

    python benchmarks/mutation.py                      # 120 sampled mutants, ~20-40 min on 2 cores
    python benchmarks/mutation.py --sample 0           # every mutant (hours)
    python benchmarks/mutation.py --list               # only list the mutants
    python benchmarks/mutation.py --only brdflab/bsdf/fresnel.py:41:3   # one mutant, by its id

Scope: ``brdflab/bsdf``, ``brdflab/emitter``, ``brdflab/integrator`` and ``brdflab/math/warps.py``; with
``--scope PATH`` (repeatable) another package or file, judged by its own selection (:data:`SELECTIONS`:
``brdflab/stats``, ``brdflab/judges``, ``brdflab/plugins.py``, ``brdflab/scene``, ``brdflab/film.py``) or by
``--tests``.

Why a small AST mutator of our own instead of ``mutmut``/``cosmic-ray``: mutmut 3 mutates only inside
functions (module-level constants such as ``P_SPECULAR_MAX`` or ``INV_PI`` are left alone), runs through
trampolines in a ``mutants/`` copy and first collects per-test coverage over the whole selection, and has no
built-in way to run a bounded random sample of mutants on a shared machine; cosmic-ray needs a session
database and a distributor. Here each mutant is one source edit found by walking the AST, applied to a
temporary copy of the repository, and judged by the fast test selection (:data:`TESTS`, in order, stopping
at the first failure) with a per-mutant timeout.

Operators (one edit per mutant): arithmetic ``+ − * / **`` swapped (``+``↔``−``, ``*``↔``/``, ``**`` → ``*``);
comparisons ``<``↔``<=``, ``>``↔``>=``, ``==``↔``!=``; numeric literals c → c + 1 (integers) or c · 1.1 / 1.0
for 0.0 (floats); unary minus removed; ``and``↔``or``; ``True``↔``False``. Docstrings, strings, annotations,
``raise`` statements and ``__all__`` are not mutated.

A mutant is *killed* when a test fails (or the selection times out), *survives* otherwise. The score is
killed / (all − equivalent); equivalent mutants (no observable change) are listed in :data:`EQUIVALENT`
with the reason, after review of the survivors. Results go to ``benchmarks/mutation_results.json``.
"""

from __future__ import annotations

import argparse
import ast
import json
import os
import random
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCOPE = ["brdflab/bsdf", "brdflab/emitter", "brdflab/integrator", "brdflab/math/warps.py"]
#: The fast test selection, run in this order with -x (the cheapest, most discriminating first).
TESTS = [
    "tests/test_golden.py",
    "tests/test_hostile.py::test_area_radiance_times_scale_bound_is_inclusive",
    "tests/test_render.py::test_irradiance_under_area_light",
    "tests/test_render.py::test_point_light_closed_form",
    "tests/test_render.py::test_hits_misses_and_occlusion",
    "tests/test_fast_vs_generic.py",
    "tests/test_light_paths.py::test_estimators_match_closed_forms",
    "tests/test_light_paths.py::test_point_light_under_mis_is_the_closed_form",
    "tests/test_validate_light.py::test_area_and_fused_light_samplers_pass",
    "tests/test_validate_light.py::test_environment_and_point_light_checks",
    "tests/test_environment.py",
    "tests/test_substrate_tir.py",
    "tests/test_light_paths.py::test_estimators_agree",
    "tests/test_light_paths.py::test_textured_area_light_is_the_closed_form",
    "tests/test_light_paths.py::test_light_facing_by_vertex_normals",
    "tests/test_light_paths.py::test_camera_rays_that_hit_a_light_see_its_radiance",
    "tests/test_light_paths.py::test_batches_of_zero_and_one_ray",
    "tests/test_light_paths.py::test_mis_parts_add_up_to_the_estimate",
    # The chi-square battery of every built-in sampler and the consistency checks (sampled ω_o follow
    # the pdf; weight = f·cos/pdf): last, since they cost the most.
    "tests/test_validate.py::test_chi2_battery_all_samplers",
    "tests/test_validate.py::test_consistency",
    "tests/test_validate.py::test_furnace",
]
DESELECT: list[str] = []
#: Further scopes (``--scope``), each with its own fast test selection (used instead of :data:`TESTS`).
SELECTIONS: dict[str, list[str]] = {
    "brdflab/stats": ["tests/test_check_calibration.py", "tests/test_intervals_by_hand.py", "tests/test_check.py",
                      "tests/test_report_runs.py"],
    "brdflab/judges": ["tests/test_chi2_machinery.py", "tests/test_agreement_by_hand.py",
                         "tests/test_external_reader_2.py", "tests/test_open_checks.py", "tests/test_validate.py",
                         "tests/test_validate_light.py", "tests/test_chi2_pages.py",
                         "tests/test_light_paths.py::test_estimators_agree",
                         "tests/test_light_paths.py::test_agreement_rejects_a_forgotten_selection_probability"],
    "brdflab/plugins.py": ["tests/test_param_conversion.py", "tests/test_plugins_registry_2.py",
                           "tests/test_plugins.py", "tests/test_open_checks.py"],
    "brdflab/scene": ["tests/test_properties_bounds.py", "tests/test_parser.py", "tests/test_render_paths_2.py",
                      "tests/test_texture_camera_2.py", "tests/test_obj_fast.py",
                      "tests/test_param_conversion.py", "tests/test_bad_inputs.py", "tests/test_golden.py",
                      "tests/test_render.py", "tests/test_light_paths.py::test_estimators_match_closed_forms",
                      "tests/test_light_paths.py::test_light_facing_by_vertex_normals",
                      "tests/test_light_paths.py::test_camera_rays_that_hit_a_light_see_its_radiance"],
    # Issue 40's packages: each with its second line of defence beside the first.
    "brdflab/kernels": ["tests/test_kernels.py", "tests/test_kernels_glue.py", "tests/test_zero_channels.py",
                        "tests/test_kernels_aot.py", "tests/test_kernel_cache.py",
                        "tests/test_light_paths.py::test_estimators_match_closed_forms",
                        "tests/test_light_paths.py::test_point_light_under_mis_is_the_closed_form",
                        "tests/test_render.py"],
    "brdflab/bsdf/measured.py": ["tests/test_measured.py", "tests/test_azimuth.py"],
    "brdflab/fitting.py": ["tests/test_measured.py", "tests/test_hostile_4.py"],
    "brdflab/stats/attribution.py": ["tests/test_attribution_2.py", "tests/test_attribution.py"],
    "brdflab/film.py": ["tests/test_film_merge.py", "tests/test_camera_film.py", "tests/test_texture_camera_2.py",
                        "tests/test_render_paths_2.py",
                        "tests/test_render.py",
                        "tests/test_golden.py::test_scene_file_defaults", "tests/test_bad_inputs.py"],
}


#: Reviewed survivors that cannot change any result: mutant id → reason.
EQUIVALENT: dict[str, str] = {
    "brdflab/plugins.py:286:16:Or->And": "the list of valid types is never empty (BUILTIN has entries for every "
    "tag), so the 'none' fallback is unreachable",
    "brdflab/plugins.py:291:57:const 1->2": "only the first close match (hint[0]) is shown",
    "brdflab/stats/render_check.py:359:76:const 1.0->1.1":
    "placeholder divisor where syy = 0, whose quotient the outer "
    "where replaces by 0",
    "brdflab/film.py:234:76:Mult->Div": "only chooses between the separable and the direct splat, which give the "
    "same sums (tests/test_film_merge.py runs both)",
    "brdflab/film.py:154:33:const 2->3": "extra taps of the table-free splat lie beyond the radius: weight 0",
    "brdflab/film.py:260:26:const 0->1": "the clamp only guards stray positions: the first tap of a sample inside "
    "the film's region is ≥ 1 (its border is ⌈r⌉ + 1 wide)",
    "brdflab/film.py:337:17:Sub->Add": "a tile lies inside the image and both films have the same border, so "
    "the tile's extent is always the smaller of the two in Film.add",
    "brdflab/scene/geometry.py:341:20:const 4->5": "only chooses between two occlusion paths with the same result",
    "brdflab/scene/geometry.py:134:100:const 0->1": "positions of a scene without meshes: no face refers to them",
    "brdflab/scene/geometry.py:186:83:const 0->1": "per-triangle flags of a scene without triangles: never read",
    "brdflab/scene/loader.py:263:18:const 0.0->1.0": "the OBJ loading time reported in the load summary (a "
    "measurement, which no test may assert)",
    "brdflab/scene/shapes.py:23:55:const 9->10": "configuration: the bump frequency of a procedural benchmark shape",
    "brdflab/scene/obj.py:407:73:const 1->2": "the fast OBJ scan then reports 'p/t' faces inconsistently and the "
    "general parser reads the file instead, with the same result",
    "brdflab/stats/render_check.py:534:52:const 1.0->1.1": "the score of a window not shown only has to be negative",
    "brdflab/stats/render_check.py:357:33:Gt->GtE": "a window without residual: 0/1 → κ clipped to 3, the value of the "
    "other branch",
    "brdflab/stats/render_check.py:589:95:const 4->5": "configuration: run_check's default number of runs (the CLI "
    "passes its own)",
    # brdflab/validate: a dead branch, defaults and the configuration of the checks (which inputs a battery
    # runs on, not how it judges them: any nearby value is an equally valid configuration).
    "brdflab/judges/material/chi2.py:243:17:Add->Sub":
    "dead branch: no caller passes max_dx/max_dy to _split_cells, so "
    "jx = jy = 0",
    "brdflab/judges/material/chi2.py:244:17:Add->Sub": "dead branch (see chi2.py:243)",
    "brdflab/judges/material/chi2.py:249:72:const 1->2": "dead branch (see chi2.py:243)",
    "brdflab/judges/material/chi2.py:378:35:const 1->2":
    "default sample count of integrate_sphere_bins: only scales the "
    "refinement tolerance (every caller of consequence passes n)",
    "brdflab/judges/core/guard.py:119:31:And->Or": "a plugin method is always called with its arrays, so len(args) > 0",
    "brdflab/judges/lights/samplers.py:226:43:const 20000->20001": "configuration: default sample count",
    "brdflab/judges/material/consistency.py:229:59:const 200000->200001": "configuration: default sample count",
    "brdflab/judges/material/battery.py:532:40:const 100000->100001": "configuration: sample cap of the light checks",
    "brdflab/judges/material/battery.py:478:14:const 30.0->33.0": "configuration: incident angle of a negative control",
    "brdflab/judges/material/stability.py:87:20:const 0.001->0.0011":
    "configuration: a roughness of the stability sweep",
    "brdflab/judges/material/stability.py:93:61:const 10.0->11.0":
    "configuration: an index ratio of the stability sweep",
    "brdflab/judges/material/consistency.py:217:29:const 3->4": "tolerance: 3 vs 4 integration errors beside the fixed "
    "1e-3 margin of ∫p ≤ 1",
    "brdflab/judges/samples/bsdf_checks.py:339:18:const 10->11":
    "a hint's minimum sample count (the hint is advice, not "
    "the verdict)",
    "brdflab/bsdf/base.py:102:55:const 1.0->1.1": "the placeholder divisor of the entries the outer where sets "
    "to 0 anyway",
    "brdflab/bsdf/diffuse.py:52:53:const 2->3": "the cosine warp reads only the first two columns of u",
    "brdflab/integrator/common.py:76:33:const 3->4": "background() returns zeros only for empty batches or "
    "scenes without an environment, where no caller assigns them",
    "brdflab/emitter/environment.py:191:44:Gt->GtE": "cells of zero weight are never drawn by the alias table, so a "
    "sampled direction never has pdf 0",
    "brdflab/bsdf/family.py:44:26:Eq->NotEq": "column 0 always equals itself, so the mutated test never skips a "
    "slot: a table is also built for a slot that is equal in all members, which gives the same per-point values",
    "brdflab/bsdf/family.py:55:28:const 0->1": "members of a family share class and scalar parameters and every "
    "texture slot is replaced by the per-point values, so copying member 1 instead of member 0 is the same",
    "brdflab/bsdf/microfacet.py:35:9:Gt->GtE": "at cos θ_h = 0 the division gives a non-finite D, which the "
    "isfinite mask sets to 0 as before",
    "brdflab/bsdf/roughconductor.py:107:49:const 1.0->1.1": "ω_h·ω_i of unit vectors never exceeds 1 (by more "
    "than an ulp), so clipping at 1.1 instead of 1 changes nothing",
    "brdflab/bsdf/roughsubstrate.py:112:57:const 1.0->1.1": "as for the conductor: ω_h·ω_i ≤ 1",
    "brdflab/bsdf/fresnel.py:30:10:GtE->Gt": "at sin²θ_t = 1 exactly, cos θ_t = 0 and r_s = r_p = 1, so F = 1 "
    "either way",
    "brdflab/bsdf/fresnel.py:30:20:const 1.0->1.1": "for 1 ≤ sin²θ_t < 1.1 cos θ_t is clamped to 0, so r_s = r_p "
    "= 1 and F = 1, the TIR value",
    "brdflab/emitter/area.py:313:48:Gt->GtE": "AreaLightSet is built only when AreaLightSet.applies() holds, which "
    "requires every area > 0",
    "brdflab/emitter/area.py:311:52:Gt->GtE": "as above: every area is > 0 when the fused set is built",
    "brdflab/integrator/direct_whitted.py:36:55:Gt->GtE": "tracing shadow rays also for zero contributions "
    "changes only the work: each such contribution is 0 · V = 0",
    "brdflab/bsdf/roughsubstrate.py:147:65:const 2->3": "the Beckmann warp reads only the first two columns of u",
    "brdflab/emitter/environment.py:185:53:const 2->3": "the sphere warp reads only the first two columns of u",
    "brdflab/bsdf/family.py:40:11:Gt->GtE": "a family of one member has no slot that varies, so building its "
    "tables finds nothing to tabulate",
    "brdflab/integrator/common.py:112:101:const 1->2": "the miss entry −1 → −2: every reader tests ≥ 0 (by_group "
    "skips negative ids), so any negative value means 'no emitter'",
    "brdflab/emitter/environment.py:177:25:Gt->GtE": "at sin θ = 0 the division gives a non-finite pdf, which "
    "the isfinite test sets to 0 as before",
    "brdflab/emitter/area.py:104:83:const 1e-12->1.1000000000000002e-12": "a 10 % wider tolerance of the planarity "
    "test: light normals are either equal to the bit or differ by far more",
    "brdflab/emitter/area.py:95:57:const 0.0->1.0": "a flat light then takes the mirrored-light branch, which "
    "sets the same normals (the vertex normal, renormalised) and marks it flat",
    "brdflab/bsdf/roughsubstrate.py:56:16:True->False": "the material-family fast path is off: it is bit-identical "
    "to the per-material path (tests/test_plugins.py, test_fast_vs_generic.py)",
    "brdflab/emitter/environment.py:88:74:const 4.0->4.4": "a constant factor of the sampling weights, which the "
    "2-D distribution normalises away",
    "brdflab/emitter/environment.py:187:43:const 2->3": "the 2-D distribution reads only the first two columns of u",
    "brdflab/bsdf/fresnel.py:25:19:GtE->Gt": "at cos θ_i = 0 exactly, F = 1 from either side (grazing reflection "
    "or total internal reflection), so which side the point counts as changes nothing",
    "brdflab/integrator/direct_whitted.py:36:35:Gt->GtE": "a sample of pdf 0 carries radiance 0, which the "
    "radiance·f > 0 test beside it already drops",
    "brdflab/bsdf/diffuse.py:43:31:Gt->GtE": "f at cos θ_o = 0 exactly: a set of measure zero, and every use "
    "multiplies f by cos θ_o = 0",
    "brdflab/bsdf/roughsubstrate.py:120:35:Gt->GtE": "p_mf at ω_i·ω_h = 0 exactly: a set of measure zero (a sampled "
    "ω_o there is a grazing reflection whose f is 0)",
    "brdflab/emitter/environment.py:123:39:const 1.0->1.1": "the y component of a unit direction never exceeds 1",
    "brdflab/integrator/common.py:297:11:Eq->NotEq": "for several groups the first one's slice cannot cover all m "
    "points, so the shortcut stays off; for one group the assembling path gives the same arrays",
    "brdflab/integrator/common.py:382:57:const 4->5": "u has exactly 4 columns here, so u[:, 1:5] is u[:, 1:4]",
    "brdflab/integrator/common.py:378:7:Or->And": "sample_lights is only called for scenes with emitters, and an "
    "empty batch runs an empty loop to the same zero arrays",
    "brdflab/integrator/common.py:228:31:Gt->GtE": "np.unique and the bincount scan give the same sorted groups; "
    "the threshold only picks the cheaper one",
    "brdflab/integrator/common.py:142:44:True->False": "codes and sizes always have the same length, so zip's "
    "strictness never matters",
    "brdflab/emitter/area.py:101:23:True->False": "the light then keeps its (equal) vertex normals and "
    "interpolates them per sample: the same normals, more work",
    "brdflab/emitter/area.py:99:27:const 0->1": "as above: unit vertex normals skip the branch and are "
    "interpolated per sample to the same values",
    "brdflab/integrator/direct_mis.py:87:31:const 3->4": "a fourth column of zeros that accumulate() and "
    "set_rows() never read",
    "brdflab/integrator/common.py:228:31:Sub->Add": "as above: it only picks np.unique or the bincount scan",
    "brdflab/bsdf/diffuse.py:43:14:Gt->GtE": "f at cos θ_i = 0 exactly: measure zero, and such camera hits are "
    "grazing points whose every use multiplies by a cosine or a pdf of 0",
    "brdflab/integrator/common.py:229:7:LtE->Lt": "with exactly 8 groups the stable argsort path yields the same "
    "groups in the same order with the same ascending indices as the per-group comparisons",
}


@dataclass
class Mutant:
    """One source edit."""

    path: str
    line: int
    col: int
    kind: str
    before: str
    after: str

    @property
    def id(self) -> str:
        return f"{self.path}:{self.line}:{self.col}:{self.kind}"


ARITH = {ast.Add: ast.Sub, ast.Sub: ast.Add, ast.Mult: ast.Div, ast.Div: ast.Mult, ast.Pow: ast.Mult}
COMPARE = {ast.Lt: ast.LtE, ast.LtE: ast.Lt, ast.Gt: ast.GtE, ast.GtE: ast.Gt, ast.Eq: ast.NotEq, ast.NotEq: ast.Eq}


def _skip_nodes(tree: ast.AST) -> set[int]:
    """ids of nodes whose subtrees are not mutated (docstrings, annotations, raise, __all__)."""
    skip: set[int] = set()

    def mark(node):
        for n in ast.walk(node):
            skip.add(id(n))

    for node in ast.walk(tree):
        if isinstance(node, ast.Raise):
            mark(node)
        elif isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str):
            mark(node)
        elif isinstance(node, ast.arg) and node.annotation is not None:
            mark(node.annotation)
        elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and node.returns is not None:
            mark(node.returns)
        elif isinstance(node, ast.AnnAssign):
            mark(node.annotation)
        elif isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets):
            mark(node)
        elif isinstance(node, ast.Call) and getattr(node.func, "attr", "") in ("errstate", "warn"):
            mark(node)
    return skip


def _variants(node: ast.AST) -> list[tuple[str, ast.AST]]:
    """(kind, mutated copy of ``node``) for every operator that applies to the node itself."""
    import copy

    out = []
    if isinstance(node, ast.BinOp) and type(node.op) in ARITH:
        m = copy.deepcopy(node)
        m.op = ARITH[type(node.op)]()
        out.append((f"{type(node.op).__name__}->{type(m.op).__name__}", m))
    elif isinstance(node, ast.AugAssign) and type(node.op) in ARITH:
        m = copy.deepcopy(node)
        m.op = ARITH[type(node.op)]()
        out.append((f"aug {type(node.op).__name__}->{type(m.op).__name__}", m))
    elif isinstance(node, ast.Compare):
        for i, op in enumerate(node.ops):
            if type(op) in COMPARE:
                m = copy.deepcopy(node)
                m.ops[i] = COMPARE[type(op)]()
                out.append((f"{type(op).__name__}->{type(m.ops[i]).__name__}", m))
    elif isinstance(node, ast.Constant) and type(node.value) in (int, float):
        v = node.value
        new = v + 1 if isinstance(v, int) else (v * 1.1 if v != 0 else 1.0)
        out.append((f"const {v!r}->{new!r}", ast.Constant(new)))
    elif isinstance(node, ast.Constant) and isinstance(node.value, bool):
        out.append((f"{node.value}->{not node.value}", ast.Constant(not node.value)))
    elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        out.append(("drop unary -", node.operand))
    elif isinstance(node, ast.BoolOp):
        m = copy.deepcopy(node)
        m.op = ast.Or() if isinstance(node.op, ast.And) else ast.And()
        out.append((f"{type(node.op).__name__}->{type(m.op).__name__}", m))
    return out


def find_mutants(path: Path) -> list[Mutant]:
    """All mutants of one file (positions from the AST of its source)."""
    src = path.read_text()
    tree = ast.parse(src)
    skip = _skip_nodes(tree)
    rel = str(path.relative_to(ROOT))
    out = []
    for node in ast.walk(tree):
        if id(node) in skip or not hasattr(node, "lineno"):
            continue
        if isinstance(node, ast.Constant) and isinstance(node.value, bool):
            pass
        for kind, new in _variants(node):
            before = ast.get_source_segment(src, node)
            if before is None:
                continue
            after = ast.unparse(new)
            if not isinstance(node, ast.AugAssign | ast.Constant):
                after = f"({after})"
            out.append(Mutant(rel, node.lineno, node.col_offset, kind, before, after))
    return out


def apply(src: str, m: Mutant) -> str:
    """The source with mutant ``m`` applied (its node's source segment replaced)."""
    lines = src.splitlines(keepends=True)
    offsets = [0]
    for line in lines:
        offsets.append(offsets[-1] + len(line.encode()))
    data = src.encode()
    start = offsets[m.line - 1] + m.col
    seg = m.before.encode()
    assert data[start:start + len(seg)] == seg, m.id
    return (data[:start] + m.after.encode() + data[start + len(seg):]).decode()


def scoped_files() -> list[Path]:
    files = []
    for s in SCOPE:
        p = ROOT / s
        files += sorted(p.glob("*.py")) if p.is_dir() else [p]
    return [f for f in files if f.name != "__init__.py" or f.stat().st_size > 200]


def copy_tree(dst: Path) -> None:
    """Copy the parts of the repository that the tests and the command line need into ``dst``."""
    for part in ("brdflab", "tests", "scenes", "references", "docs", "cli", "examples", "pyproject.toml"):
        src = ROOT / part
        if src.is_dir():
            shutil.copytree(src, dst / part, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        elif src.exists():
            shutil.copy2(src, dst / part)
    # cli/ is installed as brdflab.cli (pyproject's package-dir): the copy, imported through PYTHONPATH, needs it
    # there, or it would depend on how the editable install's finder resolves brdflab.cli
    shutil.copytree(ROOT / "cli", dst / "brdflab" / "cli", ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))


def copy_env(workdir: Path) -> dict[str, str]:
    """Environment of a subprocess that imports brdflab from the copy in ``workdir`` first."""
    return {**os.environ, "PYTHONPATH": str(workdir), "PYTHONDONTWRITEBYTECODE": "1"}


def run_tests(workdir: Path, timeout: float) -> tuple[str, str, float]:
    """('killed' | 'survived' | 'timeout', first failing test, seconds) of the selection in ``workdir``."""
    t0 = time.monotonic()
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", "-W", "ignore", *TESTS]
    for d in DESELECT:
        cmd += ["--deselect", d]
    try:
        r = subprocess.run(cmd, cwd=workdir, env=copy_env(workdir), capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return "timeout", "", time.monotonic() - t0
    failed = next((line.split()[1] for line in r.stdout.splitlines() if line.startswith(("FAILED", "ERROR"))), "")
    if failed and os.environ.get("MUTATION_VERBOSE"):
        print("\n".join(r.stdout.splitlines()[-40:]), flush=True)
    return ("survived" if r.returncode == 0 else "killed"), failed, time.monotonic() - t0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sample", type=int, default=120, help="random sample of mutants (0: all; default 120)")
    ap.add_argument("--seed", type=int, default=15)
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per mutant (a timeout counts as killed)")
    ap.add_argument("--budget", type=float, default=0.0, help="stop after this many seconds (0: no limit)")
    ap.add_argument("--only", action="append", default=[], help="mutant id prefix (repeatable; sampled too)")
    ap.add_argument("--list", action="store_true", help="list the mutants and exit")
    ap.add_argument("--summarize", type=Path, help="recompute the summary of a results .jsonl (current EQUIVALENT)")
    ap.add_argument("-o", "--output", type=Path, default=ROOT / "benchmarks" / "mutation_results.json")
    ap.add_argument("--scope", action="append", default=[],
                    help=f"mutate these paths instead (repeatable; with its test selection: {', '.join(SELECTIONS)})")
    ap.add_argument("--tests", action="append", default=[], help="test selection instead of the scope's (repeatable)")
    args = ap.parse_args(argv)
    if args.scope:
        SCOPE[:] = args.scope
        TESTS[:] = [t for s in args.scope for t in SELECTIONS.get(s, [])] or TESTS
    if args.tests:
        TESTS[:] = args.tests

    if args.summarize:
        rows = [json.loads(line) for line in args.summarize.read_text().splitlines() if line.strip()]
        for r in rows:
            r["equivalent"] = EQUIVALENT.get(r["id"])
        return report(rows, args.output, {"source": str(args.summarize)})
    mutants = [m for f in scoped_files() for m in find_mutants(f)]
    print(f"{len(mutants)} mutants in {len(scoped_files())} files", flush=True)
    if args.only:
        mutants = [m for m in mutants if any(m.id.startswith(o) for o in args.only)]
    if args.sample and args.sample < len(mutants):
        # Random order (not sorted by file), so that a run cut short by --budget is still a fair sample.
        mutants = random.Random(args.seed).sample(mutants, args.sample)
    if args.list:
        for m in mutants:
            print(f"{m.id}: {m.before!r} -> {m.after!r}")
        return 0
    tmp = Path(tempfile.mkdtemp(prefix="brdflab-mutation-"))
    results = []
    t_start = time.monotonic()
    try:
        copy_tree(tmp)
        # The sources as copied: the working tree may change while the run goes on (a rebase, an edit).
        originals = {m.path: (tmp / m.path).read_text() for m in mutants}
        for m in mutants:
            apply(originals[m.path], m)  # every mutant still applies to the copied source
        status, failed, secs = run_tests(tmp, args.timeout)
        print(f"baseline: {status} in {secs:.0f} s{' (' + failed + ')' if failed else ''}", flush=True)
        if status != "survived":
            print("the unmutated selection does not pass; fix that first", file=sys.stderr)
            return 2
        for k, m in enumerate(mutants):
            if args.budget and time.monotonic() - t_start > args.budget:
                print(f"budget reached after {k} mutants", flush=True)
                break
            target = tmp / m.path
            original = originals[m.path]
            target.write_text(apply(original, m))
            try:
                status, failed, secs = run_tests(tmp, args.timeout)
            finally:
                target.write_text(original)
            eq = EQUIVALENT.get(m.id)
            results.append({**asdict(m), "id": m.id, "status": status, "killed_by": failed, "seconds": round(secs, 1),
                            "equivalent": eq})
            with open(args.output.with_suffix(".jsonl"), "a") as log:  # partial results survive an interruption
                log.write(json.dumps(results[-1]) + "\n")
            print(f"[{k + 1}/{len(mutants)}] {status:8s} {m.id}: {m.before!r} -> {m.after!r}"
                  f"{' (' + failed + ')' if failed else ''}{' [equivalent: ' + eq + ']' if eq else ''} {secs:.0f}s",
                  flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return report(results, args.output, {"seconds": round(time.monotonic() - t_start), "sample": args.sample,
                                         "seed": args.seed})


def report(results: list[dict], output: Path, extra: dict) -> int:
    """Write the summary and results to ``output`` and print the score and the survivors."""
    killed = sum(r["status"] != "survived" for r in results)
    equivalent = sum(r["status"] == "survived" and bool(r["equivalent"]) for r in results)
    survivors = [r for r in results if r["status"] == "survived" and not r["equivalent"]]
    denom = len(results) - equivalent
    score = killed / denom if denom else float("nan")
    timeouts = sum(r["status"] == "timeout" for r in results)
    summary = {"mutants_run": len(results), "killed": killed, "timeouts": timeouts,
               "equivalent": equivalent, "survived": len(survivors), "score": score, **extra}
    output.write_text(json.dumps({"summary": summary, "results": results}, indent=1))
    print(json.dumps(summary))
    for r in survivors:
        print(f"SURVIVED {r['id']}: {r['before']!r} -> {r['after']!r}")
    for r in results:
        if r["status"] == "survived" and r["equivalent"]:
            print(f"EQUIVALENT {r['id']}: {r['equivalent']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

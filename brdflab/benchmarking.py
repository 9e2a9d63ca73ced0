"""Benchmarks: samples/s, rays/s, the share of time inside Embree, load + BVH build time, peak memory.

Each (scene, integrator) case runs in a fresh Python process (``python -m brdflab.benchmarking --one …``) so
that its peak resident memory (``ru_maxrss``) belongs to that case alone; the parent collects one JSON
record per case with the median and spread over several runs, comparable across commits.

The procedural scene ``mesh1m`` is a displaced, finely tessellated sphere of ≥ 1 million triangles,
written as OBJ into a cache folder so that the OBJ parser and the BVH build are part of what is timed.
The course scenes (:data:`COURSE_CASES`) are read from ``../shared/scenes`` beside the repository and
skipped when it is absent (they are never copied into the repository).

Besides the render-only figures, every case records its **fixed costs** (process start-up and imports,
OBJ parse, BVH build, the whole load, EXR and PNG write) and the wall time of the **whole process** as
users run it: ``brdflab render SCENE --spp N`` in a fresh process, start to exit, output included.
"""

from __future__ import annotations

import json
import os
import platform
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

from brdflab.errors import BrdflabError, clean

ROOT = Path(__file__).resolve().parent.parent

#: Fixed bench cases: name → (scene path relative to the repository, integrators).
CASES: dict[str, tuple[str, tuple[str, ...]]] = {
    "cbox_spheres": ("scenes/cbox/cbox_spheres.xml", ("direct_ems", "direct_mats", "direct_mis")),
    "veach": ("scenes/veach/veach_mis.xml", ("direct_ems", "direct_mats", "direct_mis")),
    "envlit": ("scenes/envlit/envlit_mis.xml", ("direct_ems", "direct_mats", "direct_mis")),
    "mesh1m": ("<generated>", ("direct_ems",)),
}
#: Course scenes (read from ``../shared`` when present): name → (path relative to the repository, the
#: scene's own integrator).
COURSE_CASES: dict[str, tuple[str, tuple[str, ...]]] = {
    "table_ems": ("../shared/scenes/assignment-2/table/table_ems.xml", ("direct_ems",)),
    "cbox_conductors_ems": ("../shared/scenes/assignment-3/cbox/cbox_conductors_ems.xml", ("direct_ems",)),
    "cbox_substrate_ems": ("../shared/scenes/assignment-3/cbox/cbox_substrate_ems.xml", ("direct_ems",)),
    "veach_ems": ("../shared/scenes/assignment-3/veach_mi/veach_ems.xml", ("direct_ems",)),
    "veach_mats": ("../shared/scenes/assignment-3/veach_mi/veach_mats.xml", ("direct_mats",)),
    "veach_mis": ("../shared/scenes/assignment-3/veach_mi/veach_mis.xml", ("direct_mis",)),
    "cbox_path_mis": ("../shared/scenes/assignment-4/cbox/cbox_mis.xml", ("path_mis",)),
    "cbox_caustics_mis": ("../shared/scenes/assignment-4/cbox/cbox_caustics_mis.xml", ("path_mis",)),
}
CASES.update(COURSE_CASES)


@dataclass
class BenchResult:
    """Measurements of one (scene, integrator) case."""

    case: str
    integrator: str
    width: int
    height: int
    spp: int
    triangles: int
    load_seconds: float
    runs: list[dict] = field(default_factory=list)
    peak_rss_bytes: int = 0
    """Peak resident memory of the main process."""
    worker_peak_rss_bytes: int = 0
    """Peak resident memory of the largest forked worker (0 with one worker)."""
    bytes_per_triangle: float = 0.0
    """Peak resident memory added by loading the scene (OBJ parse and BVH build), per triangle."""
    fixed: dict = field(default_factory=dict)
    """Fixed costs in seconds: ``startup`` (process start to the first brdflab import done), ``obj``,
    ``bvh``, ``load`` (the whole scene load), ``write_exr`` and ``write_png`` (written in parallel), ``kernels``
    (the compiled engine's numba import and kernel load or compile; 0 with the NumPy engine)."""
    whole_seconds: list[float] = field(default_factory=list)
    """Wall time of whole ``brdflab render`` processes (filled by :func:`run_suite`)."""

    def median(self, key: str) -> float:
        """Median of ``key`` over the runs."""
        return statistics.median(r[key] for r in self.runs)

    def spread(self, key: str) -> float:
        """(max − min)/median of ``key`` over the runs."""
        vals = [r[key] for r in self.runs]
        med = statistics.median(vals)
        return (max(vals) - min(vals)) / med if med else 0.0


def mesh1m_scene(cache: Path) -> Path:
    """The ≥ 1 M-triangle bench scene (generated once into ``cache``)."""
    return mesh_scene(cache, 500, 1004, "mesh1m", "sphere1m.obj")


def mesh_scene(cache: Path, n_theta: int, n_phi: int, name: str, obj_name: str | None = None) -> Path:
    """A displaced, tessellated sphere of about 2·n_theta·n_phi triangles under a point light."""
    cache.mkdir(parents=True, exist_ok=True)
    obj = cache / (obj_name or f"sphere_{n_theta}x{n_phi}.obj")
    if not obj.exists():
        from brdflab.scene.shapes import uv_sphere, write_obj

        v, f, _, _ = uv_sphere(n_theta=n_theta, n_phi=n_phi, bumps=0.05)
        write_obj(obj, v, f, comment="procedural bench mesh written by brdflab.benchmarking")
    xml = cache / f"{name}.xml"
    xml.write_text(
        "<scene>\n  <!-- generated by brdflab.benchmarking: ~1M-triangle displaced sphere under an area light -->\n"
        '  <integrator type="direct_ems"/>\n'
        '  <camera type="perspective"><float name="fov" value="40"/><integer name="width" value="800"/>'
        '<integer name="height" value="600"/>\n'
        '    <transform name="toWorld"><lookat origin="0,0.5,4" target="0,0,0" up="0,1,0"/></transform></camera>\n'
        f'  <mesh type="obj"><string name="filename" value="{obj.name}"/>'
        '<bsdf type="diffuse"><color name="albedo" value="0.6,0.6,0.6"/></bsdf></mesh>\n'
        '  <emitter type="pointlight"><point name="position" value="3,4,3"/>'
        '<color name="radiance" value="30,30,30"/></emitter>\n</scene>\n')
    return xml


def run_one(scene_path: Path, integrator: str, spp: int, runs: int, workers: int | None, case: str,
            plugins: list[str] | None = None) -> BenchResult:
    """Measure one case in this process (call it in a fresh process for meaningful peak memory).

    ``integrator`` "" means the scene's own; ``plugins`` are ``--plugin`` specs loaded first (a user's scene).
    """
    from brdflab.imageio import write_images
    from brdflab.plugins import load_plugins
    from brdflab.renderer import render
    from brdflab.scene.loader import load_scene
    from brdflab.timing import process_seconds

    startup = process_seconds()
    load_plugins(plugins)
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    t0 = time.perf_counter()
    scene = load_scene(scene_path, integrator or None)
    load_s = time.perf_counter() - t0
    rss_loaded = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    from brdflab.kernels import costs, preload

    preload()  # compiled engine: numba and the cached kernels (a fixed cost, reported as "kernels")
    tris = scene.geometry.triangle_count
    res = BenchResult(case, integrator or scene.integrator_type, scene.camera.width, scene.camera.height, spp, tris,
                      load_s)
    image = None
    for k in range(runs):
        image, st = render(scene, spp=spp, seed=k, workers=workers)
        res.runs.append({"seconds": st.seconds, "samples_per_s": st.samples_per_second,
                         "rays_per_s": st.rays_per_second, "embree_share": st.embree_share,
                         "ray_seconds": st.ray_seconds, "workers": st.workers})
    # Forked workers share the scene with this process copy-on-write; their peak (which counts the shared
    # pages too) is the largest of any one process.
    res.peak_rss_bytes = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    res.worker_peak_rss_bytes = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024
    res.bytes_per_triangle = (rss_loaded - rss0) / tris if tris else 0.0
    write = (0.0, 0.0)
    if image is not None:
        with tempfile.TemporaryDirectory() as tmp:
            write = write_images(Path(tmp) / "bench.exr", Path(tmp) / "bench.png", image)
    t = scene.timings
    res.fixed = {"startup": startup, "obj": t.get("obj", 0.0), "bvh": t.get("bvh", 0.0), "load": load_s,
                 "write_exr": write[0], "write_png": write[1], "kernels": sum(costs().values())}
    return res


def brdflab_command() -> list[str]:
    """The ``brdflab`` console script of this environment (as users run it)."""
    exe = Path(sys.executable).parent / "brdflab"
    found = str(exe) if exe.exists() else shutil.which("brdflab")
    if found is None:
        raise FileNotFoundError("the brdflab command is not installed (pip install -e .)")
    return [found]


def ensure_bytecode() -> bool:
    """Compile brdflab's Python sources to bytecode (``__pycache__``) where it is missing or stale, as a
    regular ``pip install`` does and as Python does on a first import; True when all of it is there.

    Whole-process timings measure what users wait for run after run. Without bytecode every process compiles
    brdflab's sources again (about 0.05–0.1 s of start-up), for instance in an editable install under
    ``PYTHONDONTWRITEBYTECODE=1``, which stops Python from writing the cache on import.
    """
    import compileall

    return all([compileall.compile_dir(str(d), quiet=2) for d in (ROOT / "brdflab", ROOT / "cli") if d.is_dir()])


def whole_process_seconds(scene_path: Path, integrator: str, spp: int, workers: int | None, seed: int = 0,
                          plugins: list[str] | None = None) -> float:
    """Wall time of one ``brdflab render`` process (start-up, load, render, EXR + PNG write, exit), with
    brdflab's bytecode in place (:func:`ensure_bytecode`)."""
    ensure_bytecode()
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [*brdflab_command(), "render", str(scene_path), "--spp", str(spp), "--seed", str(seed),
               "-o", str(Path(tmp) / "whole.exr"), "--quiet"]
        cmd += ["--integrator", integrator] if integrator else []
        for spec in plugins or []:
            cmd += ["--plugin", spec]
        if workers:
            cmd += ["--workers", str(workers)]
        t0 = time.perf_counter()
        out = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
        seconds = time.perf_counter() - t0
    if out.returncode != 0:
        raise BrdflabError(f"brdflab render {clean(scene_path, 80)} failed: {last_line(out.stderr)}")
    return seconds


def last_line(stderr: str) -> str:
    """The last non-empty line of a child's standard error: its one-line error (``brdflab: error: …``, the prefix
    dropped), or a traceback's last line."""
    lines = [ln.strip() for ln in (stderr or "").splitlines() if ln.strip()]
    return clean(lines[-1].removeprefix("brdflab: error: "), 300) if lines else "no message"


def is_scene_case(case: str) -> bool:
    """True when a bench case names a scene file of the user's (``my_scene.xml``) rather than a fixed case."""
    return case not in CASES and case.lower().endswith(".xml")


def case_scene(case: str) -> Path:
    """The scene file of a bench case (generating ``mesh1m`` if needed; a user's scene as given)."""
    if is_scene_case(case):
        return Path(case).resolve()
    rel = CASES[case][0]
    return mesh1m_scene(ROOT / ".bench-cache") if rel == "<generated>" else (ROOT / rel).resolve()


def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``, else :func:`platform.processor`), e.g. ``"AMD EPYC"``."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                if line.startswith(("model name", "Model", "Hardware")) and ":" in line:
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown CPU"


def simd() -> str:
    """The widest x86 vector extension the CPU reports (``AVX-512``, ``AVX2``, ``AVX``, ``SSE4.2``), or ``""``:
    what vectorising renderers (Mitsuba's ``llvm_ad_rgb``) pack their lanes with."""
    try:
        flags = set()
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                if line.startswith("flags"):
                    flags = set(line.split(":", 1)[1].split())
                    break
    except OSError:
        return ""
    for flag, name in (("avx512f", "AVX-512"), ("avx2", "AVX2"), ("avx", "AVX"), ("sse4_2", "SSE4.2")):
        if flag in flags:
            return name
    return ""


def machine_line() -> str:
    """One line for every figure: CPU model, cores, SIMD, date and load (``uptime``'s 1-minute average)."""
    try:
        load = f", load average {os.getloadavg()[0]:.1f}"
    except OSError:
        load = ""
    vec = f", {simd()}" if simd() else ""
    return (f"machine: {cpu_model()}, {os.cpu_count()} cores{vec}; {time.strftime('%Y-%m-%d %H:%M %Z')}{load}")


def run_suite(cases: list[str], spp: int, runs: int, workers: int | None, out: Path | None,
              say=print, plugins: list[str] | None = None) -> list[dict]:
    """Run the named cases (each in a subprocess) and return (and optionally write) the JSON records.

    A case may also be the path of a user's scene (``.xml``; its own integrator), with ``plugins`` (``--plugin``
    specs, resolved to absolute paths) loaded in every process that renders it. The first line says the
    machine (:func:`machine_line`), which the JSON records too.
    """
    say(machine_line())
    from brdflab.kernels import ensure_built

    ensure_built()  # every case's process then loads the compiled kernels (none runs during their first build)
    records = []
    plugins = [str(Path(p).resolve()) if Path(p).exists() else p for p in plugins or []]
    for case in cases:
        integrators = ("",) if is_scene_case(case) else CASES[case][1]
        scene = case_scene(case)
        if not scene.exists():
            say(f"{case}: scene {scene} not found, skipped")
            continue
        for integ in integrators:
            cmd = [sys.executable, "-m", "brdflab.benchmarking", "--one", str(scene), integ, str(spp), str(runs),
                   str(workers or 0), case, *plugins]
            out_p = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
            if out_p.returncode != 0:  # one line: the child's error, never its traceback
                say(f"{case}{'/' + integ if integ else ''}: failed: {last_line(out_p.stderr)}")
                continue
            rec = json.loads(out_p.stdout.strip().splitlines()[-1])
            try:
                rec["whole_seconds"] = [whole_process_seconds(scene, integ, spp, workers, seed=k, plugins=plugins)
                                        for k in range(runs)]
            except BrdflabError as exc:
                say(f"{case}{'/' + integ if integ else ''}: failed: {exc}")
                continue
            r = BenchResult(**{k: v for k, v in rec.items() if k in BenchResult.__dataclass_fields__})
            rec["median"] = {k: r.median(k) for k in ("samples_per_s", "rays_per_s", "embree_share", "seconds")}
            rec["median"]["whole_seconds"] = statistics.median(r.whole_seconds)
            rec["spread"] = {k: r.spread(k) for k in ("samples_per_s",)}
            records.append(rec)
            med, spread, fx = rec["median"], rec["spread"], r.fixed
            say(f"{case:19s} {r.integrator:12s} {r.width}×{r.height} {spp:4d} spp  "
                f"{med['samples_per_s'] / 1e6:6.2f} M samples/s (±{100 * spread['samples_per_s']:.0f}%)  "
                f"{med['rays_per_s'] / 1e6:6.2f} M rays/s  Embree {100 * med['embree_share']:4.0f}%  "
                f"{r.triangles:,} tris  peak {r.peak_rss_bytes / 2**20:6.0f} MiB "
                f"({r.bytes_per_triangle:.0f} B/triangle)\n{'':19s} render {med['seconds']:6.2f} s, whole process "
                f"{med['whole_seconds']:6.2f} s; fixed: start-up {fx['startup']:.2f} s, load {fx['load']:.2f} s "
                f"(OBJ {fx['obj']:.2f}, BVH {fx['bvh']:.2f}), write EXR {fx['write_exr']:.2f} ∥ PNG "
                f"{fx['write_png']:.2f} s")
    if out is not None:
        doc = {"date": time.strftime("%Y-%m-%d %H:%M"), "machine": {"cpu": cpu_model(), "cpus": os.cpu_count(),
               "simd": simd(), "platform": platform.platform(), "python": platform.python_version()},
               "spp": spp, "runs": runs, "results": records}
        from brdflab.outputs import json_text, write_text

        write_text(out, json_text(doc, indent=2))
    return records


def _main_one(argv: list[str]) -> None:
    scene, integ, spp, runs, workers, case, *plugins = argv
    r = run_one(Path(scene), integ, int(spp), int(runs), int(workers) or None, case, plugins)
    print(json.dumps(asdict(r)))


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--one":
        try:
            _main_one(sys.argv[2:])
        except BrdflabError as exc:  # the user's scene or plugin: one line for the parent to show
            print(f"brdflab: error: {exc}", file=sys.stderr)
            sys.exit(2)

"""Scale-out on Dask: real scheduler and worker processes on 127.0.0.1, images bit-identical to local runs.

One LocalCluster (two single-threaded worker processes, no dashboard, random ports) serves the in-process
tests; the command-line tests start their own (``dask scheduler`` / ``dask worker`` subprocesses, or
``--cluster local:2``) and always tear them down.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("distributed")

from brdflab.cluster import Cluster, ClusterError, cluster_address, map_jobs, parse_address  # noqa: E402
from brdflab.errors import BrdflabError  # noqa: E402
from brdflab.imageio import read_exr_header  # noqa: E402
from brdflab.renderer import render  # noqa: E402
from brdflab.scene.loader import load_scene  # noqa: E402
from tests.conftest import ROOT  # noqa: E402


def small_cbox(tmp_path: Path, width: int = 96, height: int = 72, variant: str = "cbox_spheres_mis") -> Path:
    """The bundled Cornell box with two rough spheres at a small resolution (meshes by absolute path)."""
    text = (ROOT / "scenes" / "cbox" / f"{variant}.xml").read_text()
    text = text.replace('"meshes/', f'"{(ROOT / "scenes" / "cbox" / "meshes").as_posix()}/')
    text = text.replace('name="width" value="800"', f'name="width" value="{width}"')
    text = text.replace('name="height" value="600"', f'name="height" value="{height}"')
    path = tmp_path / f"{variant}.xml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def cluster():
    with Cluster("local:2", task_units=2) as cl:
        yield cl


def test_addresses(monkeypatch):
    assert parse_address("local:3") == ("local", 3)
    assert parse_address("local")[0] == "local"
    assert parse_address("tcp://127.0.0.1:8786") == ("remote", "tcp://127.0.0.1:8786")
    assert parse_address("127.0.0.1:8786") == ("remote", "tcp://127.0.0.1:8786")
    for bad in ("local:0", "local:x", "ftp://h:1", "tcp://", "nohost", "h:1\x1b[2J"):
        with pytest.raises(BrdflabError, match="expected tcp://HOST:PORT"):
            parse_address(bad)
    monkeypatch.delenv("BRDFLAB_CLUSTER", raising=False)
    assert cluster_address(None) is None
    monkeypatch.setenv("BRDFLAB_CLUSTER", "local:2")
    assert cluster_address(None) == "local:2"
    assert cluster_address("none") is None
    with pytest.raises(ClusterError, match="cannot reach the Dask scheduler at tcp://127.0.0.1:9"):
        Cluster("tcp://127.0.0.1:9", timeout=1)


def test_path_tracer_bit_identical_to_local(cluster, tmp_path):
    """path_mis with a mirror and a glass sphere (a wavefront of bounces per unit): the cluster's image is the
    local one to the bit."""
    scene = load_scene(small_cbox(tmp_path, variant="cbox_glass_mis"))
    ref, _ = render(scene, spp=4, seed=3, workers=1)
    img, _ = render(scene, spp=4, seed=3, cluster=cluster)
    assert ref.mean() > 0 and np.array_equal(img, ref)


def test_render_bit_identical_to_local_for_any_task_size(cluster, tmp_path):
    scene = load_scene(small_cbox(tmp_path))
    ref, _ = render(scene, spp=24, seed=5, workers=2)
    assert np.array_equal(ref, render(scene, spp=24, seed=5, workers=1)[0])
    for transfer, units in (("ship", 1), ("ship", 5), ("path", 3)):
        cluster.scene_transfer, cluster.task_units = transfer, units
        img, st = render(scene, spp=24, seed=5, cluster=cluster)
        assert np.array_equal(img, ref), (transfer, units)
        assert st.spp == 24 and st.workers == 2 and st.rays > 0
        assert 1 <= len(st.per_worker) <= 2
        assert sum(w.samples for w in st.per_worker.values()) == st.samples
    cluster.scene_transfer, cluster.task_units = "ship", 2
    # Progressive passes (checkpoints) over the cluster too; a different seed gives a different image.
    seen = []
    img, _ = render(scene, spp=8, seed=6, cluster=cluster, on_pass=lambda spp, s, film: seen.append(spp))
    assert seen == [1, 2, 4, 8]
    assert np.array_equal(img, render(scene, spp=8, seed=6, workers=2, checkpoints=(1, 2, 4))[0])
    assert not np.array_equal(img[..., 0], ref[..., 0])


def test_plugin_material_and_overrides_reach_the_workers(cluster, tmp_path):
    import brdflab as bl
    from brdflab import plugins

    text = small_cbox(tmp_path).read_text().replace('<bsdf type="roughconductor">', '<bsdf type="uniform_lambert">', 1)
    text = text.replace('<color name="R0" value="0.91, 0.92, 0.92"/><float name="alpha" value="0.3"/>', "", 1)
    (tmp_path / "plugin.xml").write_text(text)
    try:
        scene = bl.load_scene(tmp_path / "plugin.xml", width=40, height=30, emitter_selection="power",
                              plugins=[str(ROOT / "tests" / "plugins" / "uniform_lambert.py")])
        ref = bl.render(scene, spp=8, seed=3, workers=2)
        assert np.array_equal(bl.render(scene, spp=8, seed=3, cluster=cluster), ref)
    finally:
        plugins.unregister_bsdf("uniform_lambert")
        plugins.unregister_bsdf("uniform_lambert_broken")


def test_path_transfer_refuses_a_different_file(cluster, tmp_path):
    path = small_cbox(tmp_path)
    path.write_text(path.read_text().replace('value="0.3"', 'value="0.35"'))  # a scene no worker has seen
    scene = load_scene(path)
    path.write_text(path.read_text().replace('value="0.35"', 'value="0.25"'))  # the file changed after loading
    cluster.scene_transfer = "path"
    try:
        with pytest.raises(BrdflabError, match="differs from the client's"):
            render(scene, spp=2, seed=1, cluster=cluster)
    finally:
        cluster.scene_transfer = "ship"


def _square_plus(job: tuple[int, float]) -> float:
    """A job with its own random stream: the result depends on the descriptor only."""
    seed, x = job
    return float(x * x + np.random.default_rng(seed).random())


def test_map_jobs_in_job_order(cluster):
    jobs = [(s, float(s)) for s in range(7)]
    local = map_jobs(_square_plus, jobs)
    assert len(local) == 7 and all(x * x <= v < x * x + 1 for v, (_, x) in zip(local, jobs, strict=True))
    assert map_jobs(_square_plus, jobs, cluster) == local


def test_worker_killed_mid_render_gives_the_same_image(cluster, tmp_path):
    scene = load_scene(small_cbox(tmp_path))
    ref, _ = render(scene, spp=128, seed=9, workers=2)
    pids = cluster.client.run(os.getpid)
    killed: dict = {}

    def kill_busiest(frac: float, stats) -> None:
        if killed or frac < 0.2:
            return
        busy = {a: len(keys) for a, keys in cluster.client.processing().items() if keys}
        if busy:
            victim = max(busy, key=busy.get)
            os.kill(pids[victim], signal.SIGKILL)
            killed.update(addr=victim, tasks=busy[victim], frac=frac)

    img, st = render(scene, spp=128, seed=9, cluster=cluster, progress=kill_busiest)
    assert killed and killed["tasks"] >= 1 and killed["frac"] < 0.9, killed
    assert st.spp == 128
    assert np.array_equal(img, ref)
    # The nanny restarts the killed worker in the background; the tests after this one need only one worker.


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _kill_tree(procs) -> None:
    for p in procs:
        if p.poll() is None:
            p.kill()
        p.wait(timeout=30)


def _wait_for_line(proc, needle: str, timeout: float) -> list[str]:
    """Read ``proc``'s stderr lines until one contains ``needle``."""
    lines, t0 = [], time.monotonic()
    while time.monotonic() - t0 < timeout:
        line = proc.stderr.readline()
        if not line:
            break
        lines.append(line)
        if needle in line:
            return lines
    raise AssertionError(f"no '{needle}' within {timeout} s: {''.join(lines)}")


def test_scheduler_lost_keeps_completed_passes(tmp_path):
    scene = load_scene(small_cbox(tmp_path, 64, 48, "cbox_spheres"))
    bindir = Path(sys.executable).parent
    port = _free_port()
    addr = f"tcp://127.0.0.1:{port}"
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    procs = [subprocess.Popen([bindir / "dask", "scheduler", "--host", "127.0.0.1", "--port", str(port),
                               "--no-dashboard"], **quiet)]
    try:
        procs.append(subprocess.Popen([bindir / "dask", "worker", addr, "--nthreads", "1", "--no-nanny", "--host",
                                       "127.0.0.1", "--no-dashboard", "--death-timeout", "20"], cwd=ROOT, **quiet))
        with Cluster(addr, timeout=30) as cl:
            def kill_scheduler(frac: float, stats) -> None:
                if stats.spp >= 64 and procs[0].poll() is None:  # a pass is complete
                    procs[0].kill()

            with pytest.raises(ClusterError, match="lost the connection to the Dask scheduler at " + addr) as err:
                render(scene, spp=100_000, seed=2, cluster=cl, progress=kill_scheduler)
        spp = err.value.stats.spp
        assert spp % 64 == 0 and 64 <= spp < 100_000
        # The completed passes are exactly the local render of that many samples.
        assert np.array_equal(err.value.image, render(scene, spp=spp, seed=2, workers=2)[0])
    finally:
        _kill_tree(procs)


def test_cli_writes_completed_passes_when_the_cluster_fails(tmp_path, monkeypatch, capsys):
    import brdflab.renderer
    from brdflab.cli.main import main

    scene = small_cbox(tmp_path, 32, 24, "cbox_spheres")
    real_render = brdflab.renderer.render

    def failing_render(sc, spp=None, **kw):
        image, stats = real_render(sc, spp=3, seed=kw.get("seed"), workers=1)
        raise ClusterError("lost the connection to the Dask scheduler at tcp://127.0.0.1:1", image, stats)

    monkeypatch.setattr(brdflab.renderer, "render", failing_render)
    monkeypatch.delenv("BRDFLAB_CLUSTER", raising=False)
    assert main(["render", str(scene), "--spp", "64", "--quiet"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"brdflab: error: lost the connection to the Dask scheduler at tcp://127.0.0.1:1; wrote the 3 "
                   f"completed spp to {tmp_path / 'cbox_spheres_partial_3spp.exr'}"]
    assert read_exr_header(tmp_path / "cbox_spheres_partial_3spp.exr")["brdflab_spp"] == "3"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cbox_spheres.xml", "cbox_spheres_partial_3spp.exr",
                                                          "cbox_spheres_partial_3spp.png"]


def _session_processes(sid: int) -> list[int]:
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                if os.getsid(int(d.name)) == sid:
                    out.append(int(d.name))
            except (ProcessLookupError, PermissionError):
                pass
    return out


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="needs /proc to list the session's processes")
def test_cli_ctrl_c_on_local_cluster_keeps_passes_and_leaves_no_process(tmp_path):
    scene = small_cbox(tmp_path, 64, 48, "cbox_spheres")
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    cli = subprocess.Popen([sys.executable, "-m", "brdflab.cli.main", "render", str(scene), "--spp", "100000",
                            "--cluster", "local:2"], stderr=subprocess.PIPE, text=True, env=env, cwd=ROOT,
                           start_new_session=True)
    try:
        _wait_for_line(cli, "rendering:", 90)
        time.sleep(0.5)
        assert len(_session_processes(cli.pid)) >= 3  # brdflab and its two worker processes
        os.killpg(cli.pid, signal.SIGINT)  # as a terminal does: to the whole process group
        _, err = cli.communicate(timeout=60)
    finally:
        if cli.poll() is None:
            os.killpg(cli.pid, signal.SIGKILL)
    assert cli.returncode == 130, err
    assert "Traceback" not in err
    partial = list(tmp_path.glob("cbox_spheres_partial_*spp.exr"))
    assert len(partial) == 1, (err, list(tmp_path.iterdir()))
    deadline = time.monotonic() + 10
    while _session_processes(cli.pid) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert _session_processes(cli.pid) == []


def test_slurm_example_builds_a_job_script():
    pytest.importorskip("dask_jobqueue")
    import runpy

    example = runpy.run_path(str(ROOT / "docs" / "slurm_cluster.py"))
    slurm = example["make_cluster"](queue="short", account="lab", host="127.0.0.1", dashboard_address=None)
    try:
        script = slurm.job_script()
    finally:
        slurm.close()
    assert "#SBATCH -p short" in script and "#SBATCH -A lab" in script
    assert "--nthreads 1" in script and "distributed.cli.dask_worker" in script
    assert json.dumps(example["JOB"])  # the documented defaults are plain data


def _report_scene(tmp_path: Path) -> Path:
    return small_cbox(tmp_path, 32, 24, "cbox_spheres")


def test_report_on_the_cluster_gives_the_same_numbers(cluster, tmp_path, monkeypatch):
    from brdflab.cli.main import main

    scene = _report_scene(tmp_path)
    args = ["report", str(scene), "--spp", "1,4", "--ref-spp", "8", "--integrators", "direct_ems,direct_mis",
            "--runs", "1", "--no-flip", "--no-mis-weights"]
    monkeypatch.delenv("BRDFLAB_CLUSTER", raising=False)
    assert main([*args, "-o", str(tmp_path / "local")]) == 0
    monkeypatch.setenv("BRDFLAB_CLUSTER", cluster.client.scheduler.address)  # the environment variable route
    assert main([*args, "-o", str(tmp_path / "cluster")]) == 0

    def numbers(folder: str) -> list[tuple]:
        rows = json.loads((tmp_path / folder / "results.json").read_text())["checkpoints"]
        return [(r["integrator"], r["spp"], r["relmse"], r["mse"], r["mape"], r["bias"]) for r in rows]

    assert numbers("local") == numbers("cluster") and len(numbers("local")) == 2 * 3  # 1, 2, 4 spp each


def test_validation_sweep_on_the_cluster_gives_the_same_results(cluster, tmp_path):
    from brdflab import plugins
    from brdflab.cli.main import main
    from brdflab.cluster import user_bsdf_classes
    from brdflab.judges.material.battery import consistency_job, plan, run_chi2

    plugins.load_plugin(ROOT / "tests" / "plugins" / "uniform_lambert.py")  # a user BSDF: shipped to the workers
    try:
        tests = plan(["roughconductor", "uniform_lambert"], ["beckmann"], alphas=(0.1,), thetas=(30.0,))
        here, there = run_chi2(tests, 20_000, 0.002), run_chi2(tests, 20_000, 0.002, cluster=cluster)
        jobs = [(name, a, 45.0, 20_000, {}, user_bsdf_classes()) for name, a in (("roughconductor", 0.1),
                                                                                  ("uniform_lambert", None))]
        cons_here, cons_there = map_jobs(consistency_job, jobs), map_jobs(consistency_job, jobs, cluster)
    finally:
        plugins.unregister_bsdf("uniform_lambert")
        plugins.unregister_bsdf("uniform_lambert_broken")
    assert len(here) == 3 and [(r.name, r.params, r.p_value) for r in here] == [
        (r.name, r.params, r.p_value) for r in there]
    assert [vars(r) for r in cons_here] == [vars(r) for r in cons_there]
    # The command line: chi2 --cluster ADDRESS.
    out = tmp_path / "chi2"
    assert main(["chi2", "--warp", "cosine_hemisphere", "--samples", "20000", "--cluster",
                 cluster.client.scheduler.address, "-o", str(out)]) == 0
    assert (out / "index.html").exists()


def test_check_runs_on_the_cluster_give_the_same_verdict(cluster, tmp_path):
    from brdflab.stats.render_check import run_check

    scene = small_cbox(tmp_path, 32, 24, "cbox_spheres")
    user = [render(load_scene(scene), spp=4, seed=77, workers=1)[0]]
    kw = {"spp": 4, "runs": 2, "seed": 3, "workers": 1, "user_spp": 4}
    here = run_check(user, scene, "direct_ems", **kw)
    there = run_check(user, scene, "direct_ems", map_fn=cluster.imap, **kw)
    assert np.array_equal(here.estimate, there.estimate)
    assert (here.p_value, here.bias, here.bias_p) == (there.p_value, there.bias, there.bias_p)

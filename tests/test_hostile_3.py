"""Hostile inputs, part 3 (issue 28): one test per class of the issue, each with several cases, mostly at the
API level (the command line is thin); the few CLI-specific cases run in-process through ``main``.

Classes: data loss (outputs.prepare_*, --force), silent wrong results (check's inputs, plugin values, strict
JSON, sys.exit in plugins), hangs and unbounded work (sample files, ω_i grouping, work estimates, α floor,
cluster addresses), tracebacks (report views of broken plugins, mathtext, FLIP, output paths, arrays).
"""

from __future__ import annotations

import json
import os
import re
import textwrap
import zipfile

import numpy as np
import pytest

from brdflab.cli.main import main
from brdflab.errors import BrdflabError, ImageError, ResourceError
from brdflab.imageio import write_exr, write_images
from tests.conftest import CAMERA, QUAD_OBJ, write_scene
from tests.test_hostile import MESH, POINT, _fails  # noqa: E402 (shared helpers)


def _scene(tmp_path, bsdf: str = "", name: str = "scene.xml"):
    return write_scene(tmp_path, '<integrator type="direct_ems"/>' + CAMERA + POINT + MESH.format(bsdf),
                       {"q.obj": QUAD_OBJ}, name=name)




def _usage_error(argv, capsys, pattern: str) -> None:
    with pytest.raises(SystemExit) as exc:
        main([str(a) for a in argv])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and re.search(pattern, err), err


PLUGIN = textwrap.dedent('''
    import sys
    import numpy as np
    import brdflab as bl

    class Hostile(bl.BSDF):
        type_name = "hostile_{mode}"

        def __init__(self, albedo=(0.5, 0.5, 0.5)):
            self.albedo = np.asarray(albedo, float)

        def eval(self, wi, wo, uv=None):
            f = (((wi[:, 2] > 0) & (wo[:, 2] > 0)) / np.pi)[:, None] * self.albedo
            mode = "{mode}"
            if mode == "nan":
                return f * np.nan
            if mode == "exit":
                sys.exit(0)
            if mode == "complex":
                return f + 1j
            if mode == "string":
                return f.astype(str)
            return f

        def pdf(self, wi, wo, uv=None):
            return np.where((wi[:, 2] > 0) & (wo[:, 2] > 0), np.maximum(wo[:, 2], 0) / np.pi, 0.0)

        def sample(self, wi, u, uv=None):
            r, phi = np.sqrt(u[:, 0]), 2 * np.pi * u[:, 1]
            wo = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(0, 1 - u[:, 0]))], 1)
            pdf = self.pdf(wi, wo)
            f = self.eval(wi, wo)
            return bl.BSDFSample(wo, np.where((pdf > 0)[:, None], f * np.pi, 0.0), pdf)
''')


def _plugin(tmp_path, mode: str):
    path = tmp_path / f"{mode}.py"
    path.write_text(PLUGIN.format(mode=mode))
    return path


# -- data loss: outputs go through brdflab.outputs -------------------------------------------------------------------
def test_made_by_brdflab_and_replaceable(tmp_path):
    from brdflab.outputs import check_replaceable, made_by_brdflab, prepare_folder, record_outputs

    mine = tmp_path / "mine.exr"
    import OpenEXR

    OpenEXR.File({"type": OpenEXR.scanlineimage}, {"RGB": np.ones((4, 4, 3), np.float32)}).write(str(mine))
    ours_exr, ours_png = tmp_path / "ours.exr", tmp_path / "ours.png"
    write_images(ours_exr, ours_png, np.ones((4, 4, 3), np.float32))
    (tmp_path / "page.html").write_text("<html>my page</html>")
    assert not made_by_brdflab(mine) and not made_by_brdflab(tmp_path / "page.html")
    assert made_by_brdflab(ours_exr) and made_by_brdflab(ours_png)
    for p in (mine, tmp_path / "page.html"):
        with pytest.raises(BrdflabError, match="brdflab did not write it.*--force"):
            check_replaceable([p])
        check_replaceable([p], force=True)
    # A folder: inputs are refused even with force; files listed in the manifest may be replaced.
    out = tmp_path / "site"
    out.mkdir()
    (out / "index.html").write_text("mine")
    with pytest.raises(BrdflabError, match="site/index.html': brdflab did not write it"):
        prepare_folder(out, ["index.html", "polar.png"])
    with pytest.raises(BrdflabError, match="it is an input of this run"):
        prepare_folder(out, ["index.html"], inputs=[out / "index.html"], force=True)
    record_outputs(out, ["index.html"])
    assert prepare_folder(out, ["index.html", "polar.png"]) is False
    (out / "chi2_view_3.png").write_text("mine")
    with pytest.raises(BrdflabError, match="chi2_view_3.png"):
        prepare_folder(out, ["chi2_view_*.png"])
    assert prepare_folder(tmp_path / "new" / "deeper", ["a.png"]) is True


@pytest.mark.parametrize("target, pattern", [
    ("file", "is an existing file, not a folder"), ("/dev/full", "is an existing file, not a folder"),
    ("input", "it is an input of this run"), ("users", "brdflab did not write it"),
])
def test_check_outputs_refused_before_the_work(tmp_path, capsys, monkeypatch, target, pattern):
    import brdflab.stats.render_check as chk

    scene = _scene(tmp_path)
    render = tmp_path / "brdflab.exr"  # a user's render named like one of check's outputs
    write_exr(render, np.ones((24, 32, 3), np.float32))
    before = render.read_bytes()
    (tmp_path / "file").write_text("x")
    users = tmp_path / "users"
    users.mkdir()
    (users / "check.html").write_text("my notes")
    out = {"file": tmp_path / "file", "/dev/full": "/dev/full", "input": tmp_path, "users": users}[target]
    monkeypatch.setattr(chk, "reference_jobs", lambda *a, **k: pytest.fail("rendered before checking outputs"))
    _fails(["check", render, "--scene", scene, "-o", out, "--spp", "1", "--runs", "2", "--quiet"], capsys, pattern)
    assert render.read_bytes() == before and (users / "check.html").read_text() == "my notes"


def test_output_folder_not_writable(tmp_path, monkeypatch):
    from brdflab.outputs import prepare_files, prepare_folder

    def denied(*args, **kwargs):  # a read-only folder (tests may run as root, where chmod does not deny)
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr("tempfile.mkstemp", denied)
    with pytest.raises(BrdflabError, match=r"-o '.*ro': cannot write to '.*': Permission denied"):
        prepare_folder(tmp_path / "ro", ["check.html"])
    with pytest.raises(BrdflabError, match="Permission denied"):
        prepare_files([tmp_path / "x.exr", tmp_path / "x.png"])


def test_plot_and_render_keep_users_files(tmp_path, capsys):
    site = tmp_path / "site"
    site.mkdir()
    (site / "index.html").write_text("my site")
    _fails(["plot", "--views", "polar", "-o", site], capsys, "site/index.html': brdflab did not write it")
    assert (site / "index.html").read_text() == "my site"
    # A Nori render beside the scene (no brdflab mark) is not replaced by `brdflab render` …
    import OpenEXR

    scene = _scene(tmp_path, name="cbox.xml")
    OpenEXR.File({"type": OpenEXR.scanlineimage}, {"RGB": np.ones((24, 32, 3), np.float32)}).write(
        str(tmp_path / "cbox.exr"))
    before = (tmp_path / "cbox.exr").read_bytes()
    _fails(["render", scene, "--spp", "1", "--workers", "1", "--quiet"], capsys, "cbox.exr': brdflab did not write")
    assert (tmp_path / "cbox.exr").read_bytes() == before
    # … unless --force; then brdflab's own pair is replaced freely.
    for _ in range(2):
        assert main(["render", str(scene), "--spp", "1", "--workers", "1", "--quiet", "--force"]) == 0


def test_heatmap_never_replaces_a_users_image(tmp_path, capsys):
    a, b = tmp_path / "a.exr", tmp_path / "b.exr"
    write_exr(a, np.ones((4, 4, 3), np.float32))
    write_exr(b, np.full((4, 4, 3), 2, np.float32))
    (tmp_path / "photo.png").write_bytes(b"\x89PNG not ours")
    _fails(["compare", a, b, "--heatmap", tmp_path / "photo.png"], capsys, "photo.png': brdflab did not write")
    assert (tmp_path / "photo.png").read_bytes() == b"\x89PNG not ours"
    capsys.readouterr()


# -- silent wrong results ---------------------------------------------------------------------------------------------
def test_check_inputs_without_meaning_are_refused():
    from brdflab.stats.render_check import Estimate, check_images, check_inputs

    rng = np.random.default_rng(3)
    big = rng.random((300, 257, 3))  # sides above 255
    with pytest.raises(ImageError, match="are the same image"):
        check_inputs([big, rng.random((300, 257, 3)), big.copy()])
    img = rng.random((32, 32, 3))
    with pytest.raises(ImageError, match="'a.exr' and 'b.exr'|'b.exr' and 'a.exr'"):
        check_inputs([img, img.copy()], names=["a.exr", "b.exr"])
    with pytest.raises(ImageError, match="are the same image"):
        check_images([img, img.copy()], Estimate.from_runs([rng.random((32, 32, 3)) for _ in range(2)]))
    for bad in (-1.0, np.nan, np.inf):
        var = np.full((32, 32, 3), 0.1)
        var[5, 7, 1] = bad
        with pytest.raises(ImageError, match=r"variance must be finite and ≥ 0; pixel \(7, 5\)"):
            check_inputs([img], ref_var=var)
    for spp in (0, -5, 2.5):
        with pytest.raises(ImageError, match="samples per pixel must be an integer ≥ 1"):
            check_inputs([img], user_spp=spp)
    for block in (1, 33, 10**6):
        with pytest.raises(ImageError, match="block side must be between 2 and"):
            check_inputs([img], block=block)
    with pytest.raises(ImageError, match="the reference is the same image as 'render 1'"):
        check_inputs([img], ref=img.copy())
    check_inputs([img, rng.random((32, 32, 3))], np.zeros((32, 32, 3)), 4, block=32)  # all fine


def test_check_cli_values(tmp_path, capsys):
    scene = _scene(tmp_path)
    write_exr(tmp_path / "r.exr", np.ones((24, 32, 3), np.float32))
    _usage_error(["check", tmp_path / "r.exr", "--scene", scene, "--user-spp", "-5"], capsys, "--user-spp: must be")
    _usage_error(["check", tmp_path / "r.exr", "--scene", scene, "--alpha", "nan"], capsys, "--alpha: must be")
    os.link(tmp_path / "r.exr", tmp_path / "same.exr")
    _fails(["check", tmp_path / "r.exr", tmp_path / "same.exr", "--scene", scene, "--quiet"], capsys,
           "are the same image")


@pytest.mark.parametrize("mode, pattern", [
    ("nan", r"non-finite value \(nan"), ("exit", "raised SystemExit: 0"), ("complex", "returned ndarray of complex"),
    ("string", "returned ndarray of <U"),
])
def test_plugin_values_are_checked(tmp_path, mode, pattern):
    from brdflab.judges.core.guard import CheckedBSDF, PluginFault
    from brdflab.plugins import load_plugin, unregister_bsdf
    from brdflab.viz import spec as bspec
    from brdflab.viz import views

    (name,) = load_plugin(_plugin(tmp_path, mode))
    try:
        wi = np.tile([0.0, 0.0, 1.0], (4, 1))
        with pytest.raises(PluginFault, match=pattern):
            CheckedBSDF(bspec.build(bspec.resolve([name])[0]).inner).eval(wi, wi)
        # plot: an error naming the plugin, never f = 0
        with pytest.raises(BrdflabError, match=f'bsdf "{name}": {name}.eval.*' + pattern):
            views.polar([bspec.build(bspec.resolve([name])[0])], 45.0)
    finally:
        unregister_bsdf(name)


def test_plugin_exit_at_import_and_odd_paths(tmp_path):
    from brdflab.plugins import load_plugin

    (tmp_path / "bye.py").write_text("import sys\nsys.exit(0)\n")
    with pytest.raises(BrdflabError, match="failed to import: SystemExit: 0"):
        load_plugin(tmp_path / "bye.py")
    (tmp_path / "pkg").mkdir()
    with pytest.raises(BrdflabError, match="plugin file is a directory"):
        load_plugin(tmp_path / "pkg")
    os.mkfifo(tmp_path / "pipe.py")
    with pytest.raises(BrdflabError, match="plugin file is a FIFO"):
        load_plugin(tmp_path / "pipe.py")
    with pytest.raises(BrdflabError, match="plugin file not found"):
        load_plugin(tmp_path / "ghost.py")


def test_render_worker_exit_is_an_error(tmp_path, capsys):
    plugin = _plugin(tmp_path, "exit")
    scene = _scene(tmp_path, '<bsdf type="hostile_exit"/>')
    _fails(["render", scene, "--plugin", plugin, "--spp", "1", "--workers", "2", "--quiet"], capsys,
           r"scene.xml:\d+: bsdf \"hostile_exit\".*SystemExit")


def test_json_is_strict(tmp_path, capsys):
    from brdflab.outputs import json_text

    text = json_text({"a": float("nan"), "b": [np.float32(np.inf), np.int64(3)], "c": np.array([1.5, np.nan])})
    assert json.loads(text) == {"a": None, "b": [None, 3], "c": [1.5, None]}
    t, r = tmp_path / "t.exr", tmp_path / "r.exr"
    write_exr(t, np.ones((8, 8, 3), np.float32))
    write_exr(r, np.zeros((8, 8, 3), np.float32))  # black reference: relative metrics and FLIP undefined
    assert main(["compare", str(t), str(r), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["flip"] is None and d["mse"] == 1.0


@pytest.mark.parametrize("theta", [90.0, -10.0, float("nan"), 1e9])
def test_api_chi2_test_angle_range(theta):
    import brdflab as bl
    from brdflab.bsdf.roughconductor import RoughConductor

    with pytest.raises(BrdflabError, match=r"theta must be in \[0, 90\)"):
        bl.chi2_test(RoughConductor(R0=0.5, alpha=0.1), theta=theta, samples=2000)
    with pytest.raises(BrdflabError, match="samples must be an integer"):
        bl.chi2_test(RoughConductor(R0=0.5, alpha=0.1), theta=30.0, samples=-5)
    with pytest.raises(BrdflabError, match=r"theta must be in \[0, 90\)"):
        bl.consistency_test(RoughConductor(R0=0.5, alpha=0.1), theta=theta, samples=2000)
    with pytest.raises(BrdflabError, match=r"theta must be in \[0, 90\)"):
        bl.furnace_test(RoughConductor(R0=0.5, alpha=0.1), thetas=(0.0, theta), samples=2000)


# -- hangs and unbounded work ----------------------------------------------------------------------------------------
def _samples_text(path, n=60):
    rng = np.random.default_rng(1)
    u = rng.random((n, 2))
    r, phi = np.sqrt(u[:, 0]), 2 * np.pi * u[:, 1]
    wo = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - u[:, 0])], 1)
    path.write_text("\n".join(f"0 0 1 {x} {y} {z}" for x, y, z in wo) + "\n")
    return path


@pytest.mark.parametrize("kind, pattern", [
    ("fifo", "samples file is a FIFO"), ("zero", "samples file is a character device"),
    ("dir", "samples file is a directory"), ("limit", "larger than the input limit"),
    ("object", "is an object array"), ("bomb", "would need 192 MiB for the array 'samples'"),
    ("liar", r"the header claims shape \(1000000000, 6\) \(48,000,000,000 bytes\), but only 480 bytes follow"),
    ("complex", "expected a real numeric"),
])
def test_sample_files_go_through_the_input_checks(tmp_path, monkeypatch, kind, pattern):
    from brdflab.judges.samples.bsdf_checks import read_samples

    path = {"fifo": tmp_path / "s.txt", "zero": "/dev/zero", "dir": tmp_path, "limit": tmp_path / "s.txt",
            "object": tmp_path / "s.npz", "bomb": tmp_path / "s.npz", "complex": tmp_path / "s.npy",
            "liar": tmp_path / "s.npy"}[kind]
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "limit":
        _samples_text(path)
        monkeypatch.setenv("BRDFLAB_MAX_INPUT_MB", "0.0001")
    elif kind == "object":
        np.savez(path, samples=np.array([[0, 0, 1, 0, 0, 1]], dtype=object))
    elif kind == "bomb":
        with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:  # 192 MiB of zeros in a small .npz
            header = b"{'descr': '<f8', 'fortran_order': False, 'shape': (4194304, 6), }".ljust(117) + b"\n"
            header = b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little") + header
            with z.open("samples.npy", "w", force_zip64=True) as f:
                f.write(header)
                chunk = bytes(2**24)
                for _ in range(12):  # 192 MiB of zeros, compressed to a fraction of a megabyte
                    f.write(chunk)
        monkeypatch.setenv("BRDFLAB_MEMORY_LIMIT_GB", "0.1")
    elif kind == "liar":  # 480 bytes whose header claims 10⁹ rows (NumPy would allocate 48 GB first)
        header = b"{'descr': '<f8', 'fortran_order': False, 'shape': (1000000000, 6), }".ljust(117) + b"\n"
        path.write_bytes(b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little") + header + bytes(480))
    elif kind == "complex":
        np.save(path, np.ones((10, 6), complex))
    with pytest.raises(BrdflabError, match=pattern):
        read_samples(path)


def test_grouping_by_wi_is_fast_and_merges_boundaries():
    from brdflab.judges.samples.bsdf_checks import WI_TOLERANCE, group_by_wi

    rng = np.random.default_rng(0)
    wi = rng.normal(size=(100_000, 3))
    groups = group_by_wi(wi / np.linalg.norm(wi, axis=1, keepdims=True))  # was quadratic: > 60 s
    assert sum(len(g) for g in groups) == 100_000
    # Values across a cell boundary but within the tolerance are one group; file order is kept.
    t = WI_TOLERANCE
    wi = np.array([[0, 0, 1.0], [0.6, 0, 0.8], [0.6 + 0.4 * t, 0, 0.8], [0.3, 0, 0.9], [0.6 - 0.4 * t, 0, 0.8],
                   [0, 0, 1.0]])
    assert [g.tolist() for g in group_by_wi(wi)] == [[0, 5], [1, 2, 4], [3]]


def test_too_many_wi_groups_is_an_error_not_an_hour(tmp_path):
    from brdflab.judges.samples.bsdf_checks import MAX_GROUPS, check_samples

    rng = np.random.default_rng(2)
    wi = rng.normal(size=(MAX_GROUPS + 100, 3))
    wi[:, 2] = np.abs(wi[:, 2])
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    np.save(tmp_path / "s.npy", np.column_stack([wi, np.tile([0.0, 0.0, 1.0], (len(wi), 1))]))
    with pytest.raises(BrdflabError, match=r"s.npy: 10,\d{3} distinct ω_i; at most 10,000 can be tested"):
        check_samples(tmp_path / "s.npy", "diffuse")


def test_work_is_estimated_before_it_starts(tmp_path, capsys, monkeypatch):
    # Every run below is bounded even if the estimate were missing (a stop after the first pass, a time
    # limit, small sample counts under a tiny BRDFLAB_MAX_HOURS), so a regression fails instead of hanging.
    import threading

    import brdflab as bl
    from brdflab.limits import check_work
    from brdflab.renderer import render
    from brdflab.stats.render_check import run_check

    scene = bl.load_scene(_scene(tmp_path))
    for spp, pattern in ((10**30, "between 1 and 2"), (2.5, "must be an integer"), (-5, "between 1 and 2")):
        with pytest.raises(BrdflabError, match=pattern):
            bl.render(scene, spp=spp, workers=1)
    stop = threading.Event()
    with pytest.raises(ResourceError, match=r"1,125,899,906,842,624 spp with 1 worker would take at least [\d,.]+ "
                       "years .*lower the sample count, pass --time-limit SECONDS"):
        render(scene, spp=2**50, workers=1, stop=stop, on_pass=lambda *a: stop.set())
    check_work(1e30, 1, "x", time_limit=1.0)  # a time limit bounds the run …
    with pytest.raises(ResourceError, match="x would take at least"):
        check_work(1e30, 1, "x", time_limit=1e300)  # … unless it bounds nothing
    monkeypatch.setenv("BRDFLAB_MAX_HOURS", "1e-7")  # 0.36 ms: any real run is "too long"
    _fails(["render", tmp_path / "scene.xml", "--spp", "64", "--time-limit", "2", "--quiet"], capsys,
           r"would take at least .*--time-limit")
    _fails(["report", tmp_path / "scene.xml", "--spp", "4", "--runs", "2", "-o", tmp_path / "rep"], capsys,
           r"the study .* would take at least .*; lower the sample count or raise BRDFLAB_MAX_HOURS")
    with pytest.raises(ResourceError, match="brdflab's estimate"):
        run_check([np.ones((24, 32, 3))], tmp_path / "scene.xml", "direct_ems", spp=4, runs=2, workers=1)
    _fails(["chi2", "--bsdf", "diffuse", "-n", str(10**11), "-o", tmp_path / "c"], capsys,
           r"would need .* GiB for 100,000,000,000 samples per test")
    assert not (tmp_path / "rep").exists() and not (tmp_path / "c").exists()


def test_plot_limits(tmp_path, capsys, monkeypatch):
    _usage_error(["plot", "--alpha", "1e-9"], capsys, r"--alpha: must be a finite number ≥ 1e-06")
    _fails(["plot", "--bsdf", "roughconductor:alpha=1e-9", "-o", tmp_path / "p"], capsys, "alpha must be a finite")
    monkeypatch.setenv("BRDFLAB_MEMORY_LIMIT_GB", "1")
    _fails(["plot", "--samples", "100000000", "--views", "albedo", "-o", tmp_path / "p"], capsys,
           r"would need .* for 100,000,000 albedo samples")
    _fails(["chi2", "--bsdf", "roughconductor", "--param", "alpha=1e-12", "-o", tmp_path / "c"], capsys,
           "--param alpha must be a finite roughness")


@pytest.mark.parametrize("address, pattern", [
    ("local:²", "expected tcp://HOST:PORT"), ("local:10000", "at most .* local workers"),
    ("ucx://10.0.0.1:1", "only over tcp"), ("inproc://x", "only over tcp"), ("tls://h:1", "only over tcp"),
    ("tcp://h:99999", "port 1–65535"), ("local:-1", "expected tcp://"),
])
def test_cluster_addresses(address, pattern):
    from brdflab.cluster import parse_address

    with pytest.raises(BrdflabError, match=pattern):
        parse_address(address)


# -- tracebacks -------------------------------------------------------------------------------------------------------
def test_report_views_of_a_broken_plugin(tmp_path):
    from brdflab.judges.material import chi2 as c2
    from brdflab.pages import chi2_views as cv
    from brdflab.plugins import load_plugin, unregister_bsdf

    (name,) = load_plugin(_plugin(tmp_path, "exit"))
    try:
        r = c2.Chi2Result(name, {"theta": 30.0}, 1.0, 3, 0.5)
        assert cv.view_of(r, n=2000) is None  # the test's verdict stands; no crash, no exit
    finally:
        unregister_bsdf(name)


def test_dollar_signs_are_text(tmp_path):
    from brdflab.viz.figures import polar_figure, save

    fig = polar_figure(np.linspace(-90, 90, 9), np.ones((1, 9)), ["a $x$_^{ name $"], 45.0, False)
    save(fig, tmp_path / "p")
    assert (tmp_path / "p.png").stat().st_size > 0


@pytest.mark.parametrize("value", [0.0, -1.0, np.nan, 1e-8])
def test_flip_of_a_black_reference_is_undefined(value):
    from brdflab.pages.metrics import flip_error, flip_parameters

    ref = np.full((8, 8, 3), value, np.float32)
    assert flip_parameters(ref) is None
    if np.isfinite(value):  # (a NaN reference is refused by compare itself)
        assert np.isnan(flip_error(np.ones((8, 8, 3)), ref))
    assert flip_parameters(np.full((8, 8, 3), 1e-6)) is not None


def test_file_system_errors_are_one_line(tmp_path, capsys, monkeypatch):
    import brdflab.cli.compare_cmd as cc

    def vanished(*args, **kwargs):
        raise FileNotFoundError(2, "No such file or directory", str(tmp_path / "gone" / "x.png"))

    a = tmp_path / "a.exr"
    write_exr(a, np.ones((4, 4, 3), np.float32))
    monkeypatch.setattr(cc, "json_text", vanished)
    _fails(["compare", a, a, "--json"], capsys, r"gone/x.png: No such file or directory")


def test_plot_folder_removed_mid_run(tmp_path, capsys, monkeypatch):
    import shutil

    import brdflab.viz.static as st

    real = st._write_all

    def then_removed(*args):
        cards = real(*args)
        shutil.rmtree(tmp_path / "site")
        return cards

    monkeypatch.setattr(st, "_write_all", then_removed)
    _fails(["plot", "--views", "polar", "-o", tmp_path / "site" / "p"], capsys,
           r"cannot write the plots into '.*site/p': No such file or directory")

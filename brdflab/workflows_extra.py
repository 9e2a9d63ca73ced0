"""The commands' functions that complete :mod:`brdflab.workflows`: samples written by another renderer
(``chi2 --samples FILE --against NAME`` and ``--against-emitter``), the speed benchmarks (``bench``) and the live
explorer (``explore``). The command line calls these, so Python users get the same checks, files and errors,
under the command line's names (``docs/api.md``'s option table, tested against the parsers).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

from brdflab.errors import BrdflabError, clean
from brdflab.workflows import _load_plugins, _specs

#: What ``check_samples(..., output=DIR)`` writes into DIR.
SAMPLES_FILES = ("index.html", "samples_group_*.png")


def check_samples(samples: str | Path, against: str, *, alpha: float | None = None, params: dict | None = None,
                  output: str | Path | None = None, force: bool = False, plugins: Sequence[str] | str | None = None,
                  seed: int | None = None):
    """Judge a file of BSDF samples from another renderer against brdflab's ``against`` (``brdflab chi2 --samples
    FILE --against NAME``; :mod:`brdflab.judges.samples.bsdf_checks`).

    Parameters
    ----------
    samples
        The samples file (text, ``.npy`` or ``.npz``; ``docs/external-samples.md``).
    against
        A BSDF (built-in or plugin type) or a warp name.
    alpha, params
        The roughness and parameters the samples were drawn with (``--alpha``, ``--param``).
    output, force
        A folder for the HTML page (``-o``), checked before the work; ``force`` replaces files brdflab did not write.
    plugins
        ``--plugin`` specs.

    Returns
    -------
    ExternalResult
        ``passed`` and ``messages()`` (one line per ω_i group and per failure, with the hints).

    Examples
    --------
    >>> import numpy as np, tempfile, pathlib, brdflab as bl
    >>> wo = bl.warps.square_to_cosine_hemisphere(np.random.default_rng(5).random((20_000, 2)))
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "cos.npy"
    >>> np.save(p, np.column_stack([wo, wo[:, 2] / np.pi]))
    >>> bl.check_samples(p, "cosine_hemisphere").passed
    True
    """
    from brdflab.judges.samples.bsdf_checks import check_samples as judge

    _load_plugins(plugins)
    if output is not None:
        from brdflab.outputs import prepare_folder

        prepare_folder(Path(output), list(SAMPLES_FILES), [samples, *_specs(plugins)], force)
    res = judge(samples, against, alpha=alpha, params=params, seed=seed)
    if output is not None:
        from brdflab.outputs import record_outputs
        from brdflab.pages.samples_report import write_samples_report

        write_samples_report(res, Path(output))
        record_outputs(Path(output), list(SAMPLES_FILES))
    return res


def check_emitter_samples(samples: str | Path, scene: str | Path, *, index: int | None = None,
                          output: str | Path | None = None, force: bool = False,
                          plugins: Sequence[str] | str | None = None):
    """Judge a file of light samples against emitter ``index`` of ``scene`` (or its whole light) (``brdflab chi2
    --samples FILE --against-emitter SCENE[:INDEX]``; :mod:`brdflab.judges.samples.light_samples`).

    Returns
    -------
    EmitterSamplesResult
        ``passed`` and ``messages()``; ``output`` also gets ``emitter_samples.html`` and ``.json``.
    """
    from brdflab.judges.samples.light_samples import EMITTER_REPORT_FILES, write_emitter_report
    from brdflab.judges.samples.light_samples import check_emitter_samples as judge
    from brdflab.scene.loader import load_scene

    _load_plugins(plugins)
    if index is not None and (isinstance(index, bool) or not isinstance(index, int) or index < 0):
        raise BrdflabError(f"index must be a whole number ≥ 0 (an <emitter> of the scene), got {clean(index, 30)}")
    sc = load_scene(Path(scene))
    if output is not None:
        from brdflab.outputs import prepare_folder

        prepare_folder(Path(output), list(EMITTER_REPORT_FILES), [samples, scene, *sc.inputs, *_specs(plugins)],
                       force)
    target = str(scene) + ("" if index is None else f":{index}")
    res = judge(samples, sc, index, target=target)
    if output is not None:
        from brdflab.outputs import record_outputs

        write_emitter_report(res, Path(output))
        record_outputs(Path(output), list(EMITTER_REPORT_FILES))
    return res


def bench(cases: Sequence[str] | None = None, *, spp: int = 16, runs: int = 3, workers: int | None = None,
          json: str | Path | None = None, force: bool = False, plugins: Sequence[str] | str | None = None,
          progress: Callable[[str], None] | None = print) -> list[dict]:
    """Speed of the fixed bench cases or of your own scenes, each run in a fresh process (``brdflab bench``).

    Parameters
    ----------
    cases
        Names of :data:`brdflab.benchmarking.CASES` (default: all) or scene files (``.xml``, their own integrator).
    spp, runs, workers
        Samples per pixel of each run, runs per case (medians are reported), worker processes.
    json, force
        Where to write the JSON records (``--json``; nothing is written without it here), checked before the runs.

    Returns
    -------
    list[dict]
        One record per case and integrator (medians, spreads, fixed costs). A run that failed is missing (and
        said through ``progress`` in one line).
    """
    from brdflab.benchmarking import CASES, ROOT, is_scene_case, run_suite
    from brdflab.scene.loader import load_scene

    cases = list(cases) if cases is not None else list(CASES)
    _load_plugins(plugins)
    inputs = list(_specs(plugins))  # what the JSON file must never be
    for c in cases:
        if is_scene_case(c):
            inputs += load_scene(Path(c)).inputs  # a user's scene: every error (and a missing plugin) before any run
        elif c not in CASES:
            raise BrdflabError(f"unknown bench case '{clean(c)}'; valid: {', '.join(CASES)}, or a scene file (.xml)")
    missing = [c for c in cases if not is_scene_case(c) and CASES[c][0] != "<generated>"
               and not (ROOT / CASES[c][0]).is_file()]
    if missing:
        raise BrdflabError(f"bench scene of {', '.join(missing)} not found ({clean(ROOT / CASES[missing[0]][0], 100)});"
                           " nothing was run")
    out = None if json is None else Path(json)
    if out is not None:
        from brdflab.outputs import prepare_files

        prepare_files([out], inputs, force, "--json")  # not an input, not a user's file, writable: before the runs
    records = run_suite(cases, spp, runs, workers, out, say=progress or (lambda m: None),
                        plugins=list(_specs(plugins)))
    if out is not None and out.exists():
        from brdflab.outputs import record_outputs

        record_outputs(out.parent, [out.name])
    return records


def bench_expected(cases: Sequence[str]) -> int:
    """How many records :func:`bench` makes when every run succeeds."""
    from brdflab.benchmarking import CASES, is_scene_case

    return sum(1 if is_scene_case(c) else len(CASES[c][1]) for c in cases)


def explore(*, plugins: Sequence[str] | str | None = None, port: int = 5006, browser: bool = True) -> None:
    """Serve the live BRDF explorer on http://127.0.0.1:``port``/ until interrupted (``brdflab explore``): every
    built-in BSDF and the plugins' types, with their parameters as sliders.

    Raises
    ------
    BrdflabError
        The port cannot be served, or Bokeh is missing.
    """
    if isinstance(port, bool) or not isinstance(port, int) or not 1 <= port <= 65535:
        raise BrdflabError(f"port must be a whole number from 1 to 65535, got {clean(port, 30)}")
    _load_plugins(plugins)
    try:
        from brdflab.viz.explorer import serve
    except ImportError as exc:  # bokeh is a dependency; a broken install gets a clear message
        raise BrdflabError(f"the explorer needs Bokeh ({exc}); pip install -e '.[test]'") from None
    try:
        serve(port, open_browser=browser)
    except OSError as exc:
        raise BrdflabError(f"cannot serve on 127.0.0.1:{port}: {exc.strerror or exc}") from None

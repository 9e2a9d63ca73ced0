"""Independent render runs as plain function calls with explicit seeds.

Every statistic of :mod:`brdflab.stats` is computed from *independent runs*: one run is one call of
:func:`run_job` (or :func:`run_progressive`) with a :class:`RenderJob` naming the scene, the integrator
(with an optional variant, ``direct_mis:power``), the sample count and the seed. Runs share nothing, so
a list of jobs can be handed to any ``map``-like function — the built-in :func:`map` (default, one after
the other, each using all local cores), or a cluster's ``client.map`` — and the results are the same.

Seeds: run ``k`` of a study with base seed ``s`` uses ``run_seed(s, k, purpose)``, a 31-bit value drawn
from ``SeedSequence([s, k, purpose])``; the purposes keep the user-side, reference and comparison streams
apart (no two runs of a study share a random stream).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from brdflab.errors import BrdflabError

#: Stream purposes (the third SeedSequence word).
PURPOSE = {"check": 1, "report": 2, "reference": 3}


def run_seed(base: int, run: int, purpose: str) -> int:
    """Seed of run ``run`` of a study with base seed ``base`` and the given purpose (see module doc)."""
    ss = np.random.SeedSequence([int(base) & 0xFFFFFFFF, int(run), PURPOSE[purpose]])
    return int(ss.generate_state(1)[0] & 0x7FFFFFFF)


def split_spec(spec: str) -> tuple[str, str | None]:
    """``"direct_mis:power"`` → ``("direct_mis", "power")``; ``"direct_ems"`` → ``("direct_ems", None)``."""
    name, _, variant = spec.strip().partition(":")
    return name.strip(), (variant.strip() or None) if _ else None


def make_integrator(spec: str):
    """Build the integrator of ``spec`` (``NAME`` or ``NAME:VARIANT``).

    A variant sets the integrator's single string parameter (``direct_mis:power`` is
    ``<integrator type="direct_mis"><string name="heuristic" value="power"/></integrator>``).
    """
    from brdflab.scene.loader import PLUGINS, plugin_class

    name, variant = split_spec(spec)
    if name not in PLUGINS["integrator"]:
        raise BrdflabError(f"unknown integrator '{name}'; valid: {', '.join(PLUGINS['integrator'])}")
    cls = plugin_class("integrator", name)
    if variant is None:
        return cls()
    strings = [k for k, t in getattr(cls, "KNOWN", {}).items() if t == "string"]
    if len(strings) != 1:
        raise BrdflabError(f"integrator '{name}' has no variants (got '{spec}')")
    return cls(**{strings[0]: variant})


def validate_specs(specs: Iterable[str]) -> list[str]:
    """Check every integrator spec (raises :class:`BrdflabError` with the valid names); return them."""
    out = [s.strip() for s in specs if s.strip()]
    for s in out:
        make_integrator(s)
    return out


#: The path tracers: a study or check of any of them is judged against ``path_mis`` renders (global illumination).
PATH_TRACERS = ("path", "path_nee", "path_mis")


def reference_integrator(specs: Iterable[str]) -> str:
    """The integrator of brdflab's own reference for a study of ``specs``: ``path_mis`` when a path tracer is
    compared (the image holds indirect light), else ``direct_mis``.

    >>> reference_integrator(["direct_ems", "path_nee"]), reference_integrator(["direct_mis:power"])
    ('path_mis', 'direct_mis')
    """
    return "path_mis" if any(str(s).split(":")[0] in PATH_TRACERS for s in specs) else "direct_mis"


@dataclass(frozen=True)
class RenderJob:
    """One independent render run."""

    scene: Path
    integrator: str
    spp: int
    seed: int
    resolution: tuple[int, int] | None = None
    """(width, height) replacing the camera's (for quick studies and tests)."""
    workers: int | None = None
    checkpoints: tuple[int, ...] = ()


def load_for(job: RenderJob):
    """Load the scene of ``job`` with its integrator (and resolution) in place."""
    from brdflab.scene.loader import load_scene

    name, _ = split_spec(job.integrator)
    scene = load_scene(job.scene, name)
    scene.integrator = make_integrator(job.integrator)
    scene.integrator_type = name
    if job.resolution is not None:
        scene.camera.width, scene.camera.height = job.resolution
    return scene


def run_job(job: RenderJob) -> tuple[np.ndarray, float]:
    """Render ``job``; return the (H, W, 3) float32 image and the render seconds."""
    from brdflab.renderer import render

    img, stats = render(load_for(job), spp=job.spp, seed=job.seed, workers=job.workers)
    return img, stats.seconds


def run_progressive(job: RenderJob) -> list[tuple[int, float, np.ndarray]]:
    """Render ``job`` progressively; return (spp, elapsed seconds, image) at every checkpoint of
    ``job.checkpoints`` (each a pass boundary of the one run)."""
    from brdflab.renderer import render

    out: list[tuple[int, float, np.ndarray]] = []
    wanted = set(job.checkpoints) | {job.spp}

    def on_pass(spp: int, seconds: float, film) -> None:
        if spp in wanted:
            out.append((spp, seconds, film.image()))

    render(load_for(job), spp=job.spp, seed=job.seed, workers=job.workers, on_pass=on_pass,
           checkpoints=tuple(sorted(wanted)))
    return out


MapFn = Callable[[Callable, list], Iterable]

"""Lit spheres: a sphere of the material rendered by brdflab's own integrator (``direct_mis``; ``path_mis`` for
a material that transmits, whose light passes two refractions).

Two tiny Nori scenes are written into a temporary folder (a unit sphere seen from +z, 30° field of
view): one lit by a point light above the camera to the upper left (on black; the plots outline the
silhouette), one by a small procedural HDR sky
(blue above, a warm sun, dark ground; lat-long in the course orientation of
:mod:`brdflab.emitter.environment`). The scene is loaded with a placeholder material, which is then
replaced by the BSDF object itself, so built-ins with any parameters and users' plugin BSDFs render the
same way. Renders use the ordinary renderer (:func:`brdflab.renderer.render`).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from brdflab.imageio import write_exr
from brdflab.scene.shapes import uv_sphere, write_obj

#: The lights of :func:`render_spheres`, in display order.
LIGHTS = ("point light", "environment")
#: Samples per pixel of each light relative to the requested count (the sky needs more than the point light).
SPP_FACTOR = {"point light": 1, "environment": 16}  # the sky is noisy at 4x: 256 spp by default
#: Camera distance and field of view of the scenes.
DISTANCE, FOV = 4.3, 30.0


def silhouette_radius(size: int) -> float:
    """Radius in pixels of the unit sphere's silhouette in a ``size``² render."""
    return size / 2 * np.tan(np.arcsin(1.0 / DISTANCE)) / np.tan(np.radians(FOV / 2))

_CAMERA = """<camera type="perspective">
  <transform name="toWorld"><lookat origin="0, 0, {distance}" target="0, 0, 0" up="0, 1, 0"/></transform>
  <float name="fov" value="{fov}"/><integer name="width" value="{size}"/><integer name="height" value="{size}"/>
</camera>"""
_EMITTERS = {
    "point light": '<emitter type="pointlight"><point name="position" value="-3, 3.5, 4.5"/>'
                   '<color name="radiance" value="40, 40, 40"/></emitter>',
    "environment": '<emitter type="environment"><string name="filename" value="sky.exr"/>'
                   '<color name="radiance" value="255, 255, 255"/></emitter>',
}


def sky_map(width: int = 128, height: int = 1024) -> np.ndarray:
    """A small procedural HDR sky (H, W, 3) for the course lookup (:mod:`brdflab.emitter.environment`, spec §9.3).

    The lookup reads +Y from the bottom rows and places texel (c, r) at the continuous position (c, r), i.e.
    row r at θ = π(1 − r/H) and column c at φ = 2π(1 − c/W); rows wrap, so the cap θ < π/H around the zenith
    blends the last row with row 0, the nadir. A realistic sky has a dark ground at the nadir, so that cap is
    a dark spot in every glossy reflection of the zenith (it was 5.6° wide with a 32-row map); the map is
    therefore tall (1024 rows: a 0.18° cap, below a pixel of the lit-sphere views) and narrow (128 columns:
    the sky varies slowly in φ), 21 MB of sampling tables.
    """
    y, x = np.meshgrid(np.arange(height, dtype=np.float64), np.arange(width, dtype=np.float64), indexing="ij")
    theta = (1.0 - y / height) * np.pi
    phi = (1.0 - x / width) * 2 * np.pi
    d = np.stack([np.sin(theta) * np.cos(phi), np.cos(theta), np.sin(theta) * np.sin(phi)], axis=-1)
    up = d[..., 1:2]
    sky = np.where(up > 0, np.array([0.25, 0.45, 0.9]) * (0.35 + 0.65 * up) + 0.25 * (1 - up) ** 4,
                   np.array([0.12, 0.1, 0.08]))
    sun = np.array([-0.45, 0.65, 0.6])
    sun /= np.linalg.norm(sun)
    sky[(d @ sun) > np.cos(np.radians(12.0))] = np.array([12.0, 10.8, 9.0])
    return sky.astype(np.float32)


def integrator_for(bsdf) -> str:
    """``direct_mis`` (one bounce: all a convex sphere of an opaque material needs), or ``path_mis`` for a BSDF
    that transmits (the light seen through a glass sphere is refracted twice)."""
    from brdflab.viz.reflectance import transmits

    return "path_mis" if transmits(bsdf) else "direct_mis"


def write_scenes(folder: Path, size: int = 128, spp: int = 16, integrator: str = "direct_mis") -> dict[str, Path]:
    """Write the sphere, the sky and one scene per light into ``folder``; return light → scene path."""
    v, f, n, uv = uv_sphere(n_theta=48, n_phi=96)
    write_obj(folder / "sphere.obj", v, f, n, uv)
    write_exr(folder / "sky.exr", sky_map(), comments="procedural sky written by brdflab.viz.sphere")
    out = {}
    for i, light in enumerate(LIGHTS):
        path = folder / f"sphere_{i}.xml"
        path.write_text(
            f"<scene>\n  <integrator type=\"{integrator}\"/>\n"
            f"  <sampler type=\"independent\"><integer name=\"sampleCount\" value=\"{spp * SPP_FACTOR[light]}\"/>"
            "</sampler>\n  "
            + _CAMERA.format(size=size, distance=DISTANCE, fov=FOV)
            + '\n  <mesh type="obj"><string name="filename" value="sphere.obj"/><bsdf type="diffuse"/></mesh>\n  '
            + _EMITTERS[light] + "\n</scene>\n")
        out[light] = path
    return out


class SphereStage:
    """The lit-sphere scenes of one size, written and loaded once, rendered for any BSDF (the explorer's live
    sphere re-renders on every change: loading the sky's sampling tables each time took longer than a small
    render). :meth:`render` swaps the BSDF in, drops the scene's per-material tables and renders in this
    process; a lock serialises renders of the same stage (the scenes are shared)."""

    def __init__(self, size: int = 128, integrator: str = "direct_mis") -> None:
        import threading

        from brdflab.scene.loader import load_scene

        self.size = size
        self._tmp = tempfile.TemporaryDirectory(prefix="brdflab-sphere-")
        self.scenes = {light: load_scene(path) for light, path in
                       write_scenes(Path(self._tmp.name), size, integrator=integrator).items()}
        self.lock = threading.Lock()

    def render(self, bsdf, light: str, spp: int, seed: int = 0, workers: int | None = 1, stop=None) -> np.ndarray:
        """(size, size, 3) float32 image of a sphere of ``bsdf`` under ``light`` at ``spp`` samples per pixel;
        ``stop`` (a :class:`threading.Event`) ends it early (the image then holds the completed passes)."""
        from brdflab.renderer import render

        with self.lock:
            scene = self.scenes[light]
            scene.bsdfs[0] = bsdf
            for cached in ("_tables", "_area_light_set"):  # built from the previous material
                scene.__dict__.pop(cached, None)
            img, _ = render(scene, spp=spp, seed=seed, workers=workers, stop=stop)
        return img


def render_spheres(bsdfs: list, size: int = 128, spp: int = 16, seed: int = 0,
                   workers: int | None = None) -> dict[str, list[np.ndarray]]:
    """Render a sphere of each BSDF under each light; returns light → [(size, size, 3) float32 per BSDF].

    ``spp`` is the point light's sample count; the environment gets :data:`SPP_FACTOR` times as many.
    """
    stages = {name: SphereStage(size, name) for name in sorted({integrator_for(b) for b in bsdfs})}
    return {light: [stages[integrator_for(b)].render(b, light, spp * SPP_FACTOR[light], seed, workers) for b in bsdfs]
            for light in LIGHTS}

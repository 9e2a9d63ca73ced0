"""Scene assembly: :class:`ObjectSpec` tree → :class:`Scene` (spec §2.3, §2.6, §2.7, §8).

Nesting rules, singletons and defaults follow Nori: one integrator and one camera are required; the
sampler defaults to ``independent`` with 1 sample and seed 0; the camera's filter to ``gaussian``
(radius 2, σ 0.5); a mesh's BSDF to ``diffuse`` with albedo 0.5. Emitters are ordered scene-level first
(XML order), then mesh area lights (mesh order). File names resolve against the scene's folder, then
the working directory, then as given.
"""

from __future__ import annotations

import hashlib
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from brdflab.bsdf.base import BSDF
from brdflab.emitter.base import Emitter
from brdflab.errors import BrdflabError, SceneError, clean, quoted
from brdflab.film import Camera, Filter
from brdflab.math.transform import Transform
from brdflab.plugins import BUILTIN, UNSUPPORTED, build_bsdf, is_builtin, plugin_class  # noqa: F401 (re-exported)
from brdflab.scene.geometry import Geometry
from brdflab.scene.obj import Mesh, load_obj
from brdflab.scene.xmlparser import ObjectSpec, parse_scene_file
from brdflab.texture import CheckerTexture

#: The registry's tables (kept here for callers of the loader; :mod:`brdflab.plugins` owns them).
PLUGINS = BUILTIN


@dataclass
class MeshInstance:
    """A mesh with its material and (optional) area emitter."""

    mesh: Mesh
    bsdf: int
    emitter: int = -1


@dataclass
class Scene:
    """A loaded scene, ready to render."""

    path: Path
    camera: Camera
    filter: Filter
    integrator: object
    integrator_type: str
    spp: int
    seed: int
    bsdfs: list[BSDF]
    emitters: list[Emitter]
    meshes: list[MeshInstance]
    geometry: Geometry
    environment: Emitter | None = None
    mesh_bsdf: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    mesh_emitter: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    emitter_pmf: np.ndarray = field(default_factory=lambda: np.zeros(0))
    emitter_cdf: np.ndarray = field(default_factory=lambda: np.zeros(0))
    timings: dict[str, float] = field(default_factory=dict)
    """Seconds spent loading: ``"obj"`` (parsing the meshes), ``"geometry"`` (triangle tables and BVH),
    ``"bvh"`` (the Embree build alone) and ``"total"`` (the whole :func:`load_scene`)."""
    source_digest: str = ""
    """SHA-256 of the scene file as loaded (cluster workers loading the file themselves must match it)."""
    #: Every file the scene was read from (the XML, its meshes, the environment map): outputs must differ.
    inputs: list[Path] = field(default_factory=list)

    def set_emitter_selection(self, mode: str = "uniform") -> None:
        """Choose emitters uniformly (Nori's rule, default) or proportionally to their power."""
        n = len(self.emitters)
        if n == 0:
            self.emitter_pmf = np.zeros(0)
        elif mode == "uniform":
            self.emitter_pmf = np.full(n, 1.0 / n)
        elif mode == "power":
            p = np.array([max(e.power(), 0.0) for e in self.emitters])
            self.emitter_pmf = p / p.sum() if p.sum() > 0 else np.full(n, 1.0 / n)
        else:
            raise BrdflabError(f"unknown emitter selection '{mode}'; valid: uniform, power")
        self.emitter_cdf = np.cumsum(self.emitter_pmf)
        if n:
            self.emitter_cdf[-1] = 1.0


def resolve_path(scene_dir: Path, name: str) -> Path | None:
    """Resolve a file name as Nori does (scene folder, then working directory, then as given).

    The first candidate that exists is returned even if it is not a regular file, so that the reader
    can say what it is (a directory, a FIFO); names the file system cannot take are never found.
    """
    for cand in (scene_dir / name, Path.cwd() / name, Path(name)):
        try:
            if cand.exists():
                return cand
        except (OSError, ValueError):  # name too long, NUL byte
            continue
    return None


def _attach_textures(obj: object, spec: ObjectSpec) -> None:
    slots = getattr(obj, "texture_slots", ())
    for child in spec.children:
        if child.tag != "texture":
            raise child.error(f"{spec.label} cannot contain <{child.tag}>; it accepts only <texture> children "
                              f"named {', '.join(slots) or '(none)'}")
        if child.name not in slots:
            raise child.error(f'texture name "{clean(child.name)}" is not a slot of {spec.label}; valid names: '
                              f"{', '.join(slots) or 'none'}")
        if child.type != "checker":
            raise child.error(f'unknown texture type "{clean(child.type)}"; valid types: checker')
        obj.set_texture(child.name, CheckerTexture.from_properties(child.props))


def _no_children(spec: ObjectSpec) -> None:
    if spec.children:
        c = spec.children[0]
        raise c.error(f"{spec.label} cannot contain <{c.tag}>")


def _positive_int(name: str, value: object, minimum: int = 1) -> int:
    """An override given in Python: an integer ≥ ``minimum``."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise BrdflabError(f"{name} must be an integer ≥ {minimum}, got {value!r:.60}")
    return int(value)


def load_scene(path: str | Path, integrator_override: str | None = None, *, integrator: str | None = None,
               spp: int | None = None, seed: int | None = None, width: int | None = None,
               height: int | None = None, emitter_selection: str | None = None) -> Scene:
    """Parse and assemble a Nori scene file, in named steps: sort the scene's children, build the integrator,
    the camera and filter, the sampler settings, the scene-level emitters, the meshes with their materials and
    area emitters, the Embree geometry, then attach the area emitters.

    Parameters
    ----------
    path
        The scene XML file.
    integrator_override, integrator
        Replace the scene's integrator type (e.g. ``"direct_mis"``); the two names are synonyms.
    spp, seed
        Replace the sampler's ``sampleCount`` and ``seed``.
    width, height
        Replace the camera's image size (the horizontal field of view is kept, as when editing the file).
    emitter_selection
        ``"uniform"`` (Nori's rule, default) or ``"power"``.

    Raises
    ------
    BrdflabError
        For every invalid or missing input, with file and line.
    """
    t_start = time.perf_counter()
    path = Path(path)
    root = parse_scene_file(path)
    inputs = [path]
    scene_dir = path.parent

    def resolve(name: str) -> Path | None:
        found = resolve_path(scene_dir, name)
        if found is not None:
            inputs.append(found)
        return found

    override = integrator or integrator_override
    specs = _sort_children(root, path, override)
    itype = override or specs.integrator.type
    integrator_obj = _build_integrator(specs.integrator, itype)
    camera, filt = _build_camera(specs.camera, width, height)
    spp, seed = _read_sampler(specs.sampler, spp, seed)
    emitters, environment = _build_scene_emitters(specs.emitters, resolve)
    bsdfs, meshes, area_emitters, obj_seconds = _load_meshes(specs.meshes, resolve, scene_dir)
    inputs += [Path(f) for b in bsdfs for f in getattr(b, "input_files", ())]  # a measured BSDF's table
    t0 = time.perf_counter()
    geometry = Geometry([m.mesh for m in meshes])
    geometry_seconds = time.perf_counter() - t0
    _attach_area_emitters(geometry, meshes, area_emitters, emitters)

    scene = Scene(path, camera, filt, integrator_obj, itype, spp, seed, bsdfs, emitters, meshes, geometry,
                  environment, inputs=inputs)
    scene.mesh_bsdf = np.array([m.bsdf for m in meshes], dtype=np.int64)
    scene.mesh_emitter = np.array([m.emitter for m in meshes], dtype=np.int64)
    scene.set_emitter_selection(emitter_selection or "uniform")
    scene.source_digest = hashlib.sha256(path.read_bytes()).hexdigest()
    _warn_if_black(path, emitters, integrator_obj, itype)
    scene.timings = {"obj": obj_seconds, "geometry": geometry_seconds, "bvh": geometry.bvh_seconds,
                     "total": time.perf_counter() - t_start}
    return scene


@dataclass
class _Specs:
    """The scene's top-level objects, sorted by kind (XML order kept within a kind)."""

    camera: ObjectSpec
    integrator: ObjectSpec
    sampler: ObjectSpec | None
    emitters: list[ObjectSpec]
    meshes: list[ObjectSpec]


def _sort_children(root: ObjectSpec, path: Path, integrator_override: str | None) -> _Specs:
    """Step 1: check the children of ``<scene>`` (one camera, integrator, sampler, environment; known tags
    and types) and sort them."""
    root.props.check_known({})
    single: dict[str, ObjectSpec | None] = {"camera": None, "integrator": None, "sampler": None}
    env_seen = False
    scene_emitters: list[ObjectSpec] = []
    mesh_specs: list[ObjectSpec] = []
    for child in root.children:
        if child.tag in single:
            prev = single[child.tag]
            if prev is not None:
                raise child.error(f"a scene can have only one <{child.tag}> (the first is at line {prev.line})")
            single[child.tag] = child
            if child.tag == "integrator" and integrator_override is None:
                plugin_class("integrator", child.type, child)
        elif child.tag == "mesh":
            mesh_specs.append(child)
        elif child.tag == "emitter":
            if child.type == "area":
                raise child.error('an <emitter type="area"> must be placed inside a <mesh>')
            plugin_class("emitter", child.type, child)
            if child.type == "environment":
                if env_seen:
                    raise child.error("a scene can have only one environment emitter")
                env_seen = True
            scene_emitters.append(child)
        else:
            raise child.error(f"<scene> cannot contain <{child.tag}>; valid children: <mesh>, <emitter>, "
                              "<sampler>, <camera>, <integrator>")
    if single["integrator"] is None:
        raise SceneError("no <integrator> was specified", path)
    if single["camera"] is None:
        raise SceneError("no <camera> was specified", path)
    return _Specs(single["camera"], single["integrator"], single["sampler"], scene_emitters, mesh_specs)


def _build_integrator(spec: ObjectSpec, itype: str):
    """Step 2: the integrator (the override's type, or the scene's)."""
    icls = plugin_class("integrator", itype, spec)
    _no_children(spec)
    return icls.from_properties(spec.props)


def _build_camera(spec: ObjectSpec, width: int | None, height: int | None) -> tuple[Camera, Filter]:
    """Step 3: the perspective camera (size overrides applied) and its reconstruction filter."""
    if spec.type != "perspective":
        raise spec.error(f'unknown camera type "{clean(spec.type)}"; valid types: perspective')
    for key, value in (("width", width), ("height", height)):
        if value is not None:
            spec.props.set(key, "integer", _positive_int(key, value))
    camera = Camera.from_properties(spec.props)
    filt = Filter()
    for c in spec.children:
        if c.tag != "rfilter":
            raise c.error(f"<camera> cannot contain <{c.tag}>; it accepts one <rfilter>")
        if c.type not in Filter.KNOWN:
            raise c.error(f'unknown rfilter type "{clean(c.type)}"; valid types: {", ".join(Filter.KNOWN)}')
        if len([x for x in spec.children if x.tag == "rfilter"]) > 1:
            raise c.error("<camera> accepts only one <rfilter>")
        _no_children(c)
        filt = Filter.from_properties(c.type, c.props)
    return camera, filt


def _read_sampler(spec: ObjectSpec | None, spp_override: int | None, seed_override: int | None) -> tuple[int, int]:
    """Step 4: samples per pixel and seed (the ``independent`` sampler's, then the overrides)."""
    spp, seed = 1, 0
    if spec is not None:
        if spec.type != "independent":
            raise spec.error(f'unknown sampler type "{clean(spec.type)}"; valid types: independent')
        _no_children(spec)
        spec.props.check_known({"sampleCount": "integer", "seed": "integer"})
        spp = spec.props.get_int("sampleCount", 1)
        seed = spec.props.get_int("seed", 0)
        if spp < 1:
            raise spec.props.error("sampleCount", f"'sampleCount' must be at least 1, got {spp}")
    if spp_override is not None:
        spp = _positive_int("spp", spp_override)
    if seed_override is not None:
        seed = _positive_int("seed", seed_override, minimum=0)
    return spp, seed


def _build_scene_emitters(specs: list[ObjectSpec], resolve) -> tuple[list[Emitter], Emitter | None]:
    """Step 5: the emitters outside meshes (point lights, the environment), in XML order."""
    emitters: list[Emitter] = []
    environment = None
    for spec in specs:
        cls = plugin_class("emitter", spec.type, spec)
        _no_children(spec)
        if spec.type == "environment":
            em = cls.from_properties(spec.props, resolve)
            environment = em
        else:
            em = cls.from_properties(spec.props)
        emitters.append(em)
    return emitters, environment


def _mesh_children(spec: ObjectSpec) -> tuple[ObjectSpec | None, ObjectSpec | None]:
    """A mesh's ``<bsdf>`` and area ``<emitter>`` (at most one each)."""
    bsdf_spec = em_spec = None
    for c in spec.children:
        if c.tag == "bsdf":
            if bsdf_spec is not None:
                raise c.error("a <mesh> can have only one <bsdf>")
            bsdf_spec = c
        elif c.tag == "emitter":
            if em_spec is not None:
                raise c.error("a <mesh> can have only one <emitter>")
            if c.type != "area":
                raise c.error(f'<emitter type="{clean(c.type)}"> cannot be placed inside a <mesh>; only "area" can')
            em_spec = c
        else:
            raise c.error(f"<mesh> cannot contain <{c.tag}>; it accepts one <bsdf> and one <emitter>")
    return bsdf_spec, em_spec


def _mesh_bsdf(bsdf_spec: ObjectSpec | None) -> BSDF:
    """A mesh's material: the default diffuse, a built-in, or a user's BSDF checked on every call."""
    if bsdf_spec is None:
        return plugin_class("bsdf", "diffuse")(np.full(3, 0.5))
    bsdf = build_bsdf(plugin_class("bsdf", bsdf_spec.type, bsdf_spec), bsdf_spec.props)
    _attach_textures(bsdf, bsdf_spec)
    if not is_builtin(bsdf_spec.type):  # a user's BSDF: its results are checked on every call
        from brdflab.judges.core.guard import SceneCheckedBSDF

        bsdf = SceneCheckedBSDF(bsdf, bsdf_spec.file, bsdf_spec.line)
    return bsdf


def _load_meshes(specs: list[ObjectSpec], resolve, scene_dir: Path):
    """Step 6: every mesh's OBJ file, material and area emitter: (bsdfs, mesh instances, (mesh index,
    emitter, spec) of the area emitters, seconds spent parsing OBJ)."""
    bsdfs: list[BSDF] = []
    meshes: list[MeshInstance] = []
    area_emitters: list[tuple[int, Emitter, ObjectSpec]] = []
    obj_seconds = 0.0
    for spec in specs:
        if spec.type != "obj":
            raise spec.error(f'unknown mesh type "{clean(spec.type)}"; valid types: obj')
        spec.props.check_known({"filename": "string", "toWorld": "transform"})
        fname = spec.props.get_string("filename")
        fpath = resolve(fname)
        if fpath is None:
            raise spec.props.error("filename", f"mesh file {quoted(fname)} not found (looked in "
                                   f"{clean(scene_dir)} and the working directory)")
        to_world = spec.props.get_transform("toWorld", Transform())
        t0 = time.perf_counter()
        mesh = load_obj(fpath, to_world)
        obj_seconds += time.perf_counter() - t0
        bsdf_spec, em_spec = _mesh_children(spec)
        bsdfs.append(_mesh_bsdf(bsdf_spec))
        meshes.append(MeshInstance(mesh, len(bsdfs) - 1))
        if em_spec is not None:
            em = plugin_class("emitter", "area", em_spec).from_properties(em_spec.props)
            _attach_textures(em, em_spec)
            area_emitters.append((len(meshes) - 1, em, em_spec))
    return bsdfs, meshes, area_emitters, obj_seconds


def _attach_area_emitters(geometry: Geometry, meshes: list[MeshInstance], area_emitters, emitters: list) -> None:
    """Step 7: area emitters onto their meshes in the built geometry (appended after the scene-level ones)."""
    for mesh_index, em, spec in area_emitters:
        em.attach(geometry, mesh_index)
        if not em.area > 0:
            raise spec.error(f"area emitter on {quoted(meshes[mesh_index].mesh.path)} has zero surface area")
        if not np.isfinite(em.area):
            raise spec.error(f"area emitter on {quoted(meshes[mesh_index].mesh.path)} has infinite surface area")
        meshes[mesh_index].emitter = len(emitters)
        emitters.append(em)


def _warn_if_black(path: Path, emitters: list, integrator, itype: str) -> None:
    """Warn about scenes that can only render black."""
    if not emitters and getattr(integrator, "needs_emitters", False):
        warnings.warn(f"{path}: the scene has no emitter; the image will be black", stacklevel=3)
    elif emitters and itype == "direct_mats" and all(e.is_delta for e in emitters):
        warnings.warn(f"{path}: direct_mats samples the BSDF and can never hit point lights, the only emitters "
                      "of this scene; the image will be black (use direct_ems or direct_mis)", stacklevel=3)

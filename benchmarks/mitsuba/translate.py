"""Translate a brdflab (Nori) scene file into the closest Mitsuba 3 scene, for the side-by-side benchmark.

Usage::

    python benchmarks/mitsuba/translate.py SCENE.xml INTEGRATOR OUT.xml [--spp N]

What maps to what (see README.md in this folder for what differs):

==============================  ===============================================================
Nori / brdflab                  Mitsuba 3
==============================  ===============================================================
``perspective`` camera          ``perspective`` sensor, ``fov_axis="x"``, same ``lookat``/transform
default gaussian filter         ``hdrfilm`` with ``gaussian`` rfilter (σ 0.5, radius 2: the same)
``independent`` sampler         ``independent`` sampler, ``sample_count`` = spp
``mesh type="obj"``             ``shape type="obj"`` on the same OBJ file, same transform
``diffuse`` albedo              ``diffuse`` reflectance
``roughconductor`` R0, alpha    ``roughconductor`` beckmann, alpha, ``material="none"``,
                                ``specular_reflectance`` = R0 (Mitsuba has no Schlick option)
``roughsubstrate``              ``roughplastic`` beckmann, alpha, int/ext IOR, diffuse_reflectance
``area`` radiance               ``area`` emitter radiance on the shape
``pointlight`` radiance (= I)   ``point`` intensity
``environment`` (file, /255)    ``envmap`` on the same EXR, scale = radiance/255, rotated to Nori's lookup
``direct_ems/mats/mis``         ``direct`` with (emitter_samples, bsdf_samples) = (1,0)/(0,1)/(1,1)
==============================  ===============================================================
"""

from __future__ import annotations

import argparse
import os
import xml.etree.ElementTree as ET
from pathlib import Path

SAMPLES = {"direct_ems": (1, 0), "direct_mats": (0, 1), "direct_mis": (1, 1)}
#: brdflab's path tracer with MIS against Mitsuba's ``path`` (emitter and BSDF sampling at every vertex, no depth
#: cap). Mitsuba's Russian roulette is the same rule (survival min(0.95, max β), survivors divided by it); its
#: ``rr_depth`` is set to brdflab's (:data:`brdflab.integrator.path.RR_DEPTH`, the vertex it starts at) so that
#: both trace paths of the same expected length.
PATHS = {"path_mis": 3}
#: Nori's default indices of refraction for ``roughsubstrate`` (spec §10).
INT_IOR, EXT_IOR = 1.5046, 1.000277


def _props(elem: ET.Element) -> dict[str, tuple[str, ET.Element]]:
    return {c.get("name", ""): (c.tag, c) for c in elem if c.get("name") is not None}


def _value(props: dict, name: str, default: str) -> str:
    return props[name][1].get("value", default) if name in props else default


def _transform(elem: ET.Element | None, name: str = "to_world") -> str:
    if elem is None:
        return ""
    parts = []
    for c in elem:
        attrs = " ".join(f'{k}="{v}"' for k, v in c.attrib.items())
        parts.append(f"<{c.tag} {attrs}/>")
    return f'<transform name="{name}">{"".join(parts)}</transform>'


def _rgb(name: str, value: str) -> str:
    return f'<rgb name="{name}" value="{value}"/>'


def _bsdf(elem: ET.Element) -> str:
    kind = elem.get("type")
    p = _props(elem)
    if kind == "diffuse":
        return f'<bsdf type="diffuse">{_rgb("reflectance", _value(p, "albedo", "0.5, 0.5, 0.5"))}</bsdf>'
    if kind == "roughconductor":
        return ('<bsdf type="roughconductor"><string name="material" value="none"/>'
                '<string name="distribution" value="beckmann"/>'
                f'<float name="alpha" value="{_value(p, "alpha", "0.1")}"/>'
                f'{_rgb("specular_reflectance", _value(p, "R0", "1, 1, 1"))}</bsdf>')
    if kind == "roughsubstrate":
        return ('<bsdf type="roughplastic"><string name="distribution" value="beckmann"/>'
                f'<float name="alpha" value="{_value(p, "alpha", "0.1")}"/>'
                f'<float name="int_ior" value="{_value(p, "intIOR", str(INT_IOR))}"/>'
                f'<float name="ext_ior" value="{_value(p, "extIOR", str(EXT_IOR))}"/>'
                '<boolean name="nonlinear" value="false"/>'
                f'{_rgb("diffuse_reflectance", _value(p, "kd", "0.5, 0.5, 0.5"))}</bsdf>')
    if kind == "mirror":  # a perfect mirror: Mitsuba's conductor without Fresnel (reflectance 1)
        return '<bsdf type="conductor"><string name="material" value="none"/></bsdf>'
    if kind == "dielectric":  # smooth glass; both scale refracted radiance by (η_i/η_t)²
        return ('<bsdf type="dielectric">'
                f'<float name="int_ior" value="{_value(p, "intIOR", str(INT_IOR))}"/>'
                f'<float name="ext_ior" value="{_value(p, "extIOR", str(EXT_IOR))}"/></bsdf>')
    raise ValueError(f"no Mitsuba translation for bsdf type '{kind}'")


def _grey(value: str) -> float:
    parts = [float(v) for v in value.replace(",", " ").split()]
    return sum(parts) / len(parts)


def translate(scene: Path, integrator: str, out: Path, spp: int = 64) -> Path:
    """Write the Mitsuba translation of ``scene`` (rendered with ``integrator``) to ``out``."""
    root = ET.parse(scene).getroot()
    base = scene.parent.resolve()
    rel = Path(os.path.relpath(base, out.parent.resolve()))
    if integrator in PATHS:
        integ = (f'  <integrator type="path"><integer name="max_depth" value="-1"/>'
                 f'<integer name="rr_depth" value="{PATHS[integrator]}"/></integrator>')
    else:
        es, bs = SAMPLES[integrator]
        integ = (f'  <integrator type="direct"><integer name="emitter_samples" value="{es}"/>'
                 f'<integer name="bsdf_samples" value="{bs}"/></integrator>')
    lines = ['<scene version="3.0.0">',
             f'  <!-- Mitsuba 3 translation of {scene.name} for {integrator} (benchmarks/mitsuba/translate.py) -->',
             integ]
    cam = root.find("camera")
    cp = _props(cam)
    lines += ['  <sensor type="perspective">',
              f'    <float name="fov" value="{_value(cp, "fov", "30")}"/><string name="fov_axis" value="x"/>',
              f'    <float name="near_clip" value="{_value(cp, "nearClip", "1e-4")}"/>'
              f'<float name="far_clip" value="{_value(cp, "farClip", "1e4")}"/>',
              f'    {_transform(cam.find("transform"))}',
              f'    <sampler type="independent"><integer name="sample_count" value="{spp}"/></sampler>',
              f'    <film type="hdrfilm"><integer name="width" value="{_value(cp, "width", "1280")}"/>'
              f'<integer name="height" value="{_value(cp, "height", "720")}"/>'
              '<string name="pixel_format" value="rgb"/><rfilter type="gaussian"/></film>',
              '  </sensor>']
    for mesh in root.findall("mesh"):
        mp = _props(mesh)
        filename = (rel / _value(mp, "filename", "")).as_posix()
        inner = [f'<string name="filename" value="{filename}"/>', _transform(mesh.find("transform"))]
        bsdf = mesh.find("bsdf")
        em = mesh.find("emitter")
        if em is not None and integrator in PATHS:  # the course's rule: a path that hits an emitter ends there
            inner.append('<bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>')
        else:
            inner.append(_bsdf(bsdf) if bsdf is not None else _bsdf(ET.Element("bsdf", type="diffuse")))
        if em is not None:
            inner.append(f'<emitter type="area">{_rgb("radiance", _value(_props(em), "radiance", "1, 1, 1"))}'
                         "</emitter>")
        lines.append(f'  <shape type="obj">{"".join(s for s in inner if s)}</shape>')
    for em in root.findall("emitter"):
        ep = _props(em)
        kind = em.get("type")
        if kind == "pointlight":
            lines.append(f'  <emitter type="point"><point name="position" value="{_value(ep, "position", "0,0,0")}"/>'
                         f'{_rgb("intensity", _value(ep, "radiance", "1, 1, 1"))}</emitter>')
        elif kind == "environment":
            filename = (rel / _value(ep, "filename", "")).as_posix()
            scale = _grey(_value(ep, "radiance", "255, 255, 255")) / 255.0
            # Nori's lookup reads column (1 − atan2(ω_z, ω_x)/2π)·W and row (1 − arccos(ω_y)/π)·H; Mitsuba's
            # reads (atan2(v_x, −v_z)/2π, arccos(v_y)/π) of v = to_world⁻¹ ω. They agree for
            # v = (−ω_z, −ω_y, −ω_x), a rotation (its own inverse).
            lines.append(f'  <emitter type="envmap"><string name="filename" value="{filename}"/>'
                         f'<float name="scale" value="{scale:g}"/><transform name="to_world">'
                         '<matrix value="0 0 -1 0  0 -1 0 0  -1 0 0 0  0 0 0 1"/></transform></emitter>')
        else:
            raise ValueError(f"no Mitsuba translation for emitter type '{kind}'")
    lines.append("</scene>\n")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines))
    return out


def main() -> None:
    """Command line: translate one scene."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", type=Path)
    ap.add_argument("integrator", choices=sorted(SAMPLES) + sorted(PATHS))
    ap.add_argument("out", type=Path)
    ap.add_argument("--spp", type=int, default=64)
    a = ap.parse_args()
    print(translate(a.scene, a.integrator, a.out, a.spp))


if __name__ == "__main__":
    main()

"""Nori scene XML → a tree of :class:`ObjectSpec` with typed properties (spec §2–3).

The parser uses the standard library's expat binding, which reports line and column numbers, so every
error names the file, the line and what was expected. It checks the grammar only (tags, attributes,
value syntax, nesting of property and transform tags); which plugin accepts which property or child is
checked when the scene is assembled (:mod:`brdflab.scene.loader`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from xml.parsers import expat

import numpy as np

from brdflab.errors import SceneError, clean, quoted
from brdflab.limits import read_input
from brdflab.math import transform as tf
from brdflab.scene.properties import PropertyList

#: Object tags (spec §2.2).
OBJECT_TAGS = (
    "scene", "integrator", "camera", "sampler", "rfilter", "mesh", "bsdf", "emitter", "texture",
    "medium", "phase", "test",
)
#: Property tags (spec §2.4).
PROPERTY_TAGS = ("integer", "float", "boolean", "string", "point", "vector", "color", "transform")
#: Operations allowed inside ``<transform>`` (spec §3).
TRANSFORM_OPS = ("translate", "scale", "rotate", "matrix", "lookat")

_INT_RE = re.compile(r"[+-]?\d+\Z")
_FLOAT_RE = re.compile(r"\s*[+-]?(\d+\.?\d*([eE][+-]?\d+)?|\.\d+([eE][+-]?\d+)?|inf(inity)?|nan)\Z", re.I)
_SPLIT_RE = re.compile(r"[,\s]+")
#: Deepest element nesting accepted (Nori scenes need 5; 10 000-deep files must not exhaust the stack).
MAX_DEPTH = 64
#: Longest attribute value accepted (16 numbers of a <matrix> need a few hundred characters). Longer values
#: are refused before any regular expression or message sees them.
MAX_ATTRIBUTE = 4096
#: Integer properties must fit a signed 64-bit integer.
INT_LIMIT = 2**63


@dataclass
class ObjectSpec:
    """One object tag of the scene file, with its properties and child objects."""

    tag: str
    type: str
    name: str | None
    props: PropertyList
    children: list[ObjectSpec] = field(default_factory=list)
    file: str = ""
    line: int = 0

    @property
    def label(self) -> str:
        """Human-readable label, e.g. ``<bsdf type="diffuse">``."""
        return f'<{self.tag} type="{clean(self.type)}">' if self.type else f"<{self.tag}>"

    def error(self, message: str) -> SceneError:
        """A :class:`SceneError` located at this object's tag."""
        return SceneError(message, self.file, self.line)


@dataclass
class _Node:
    tag: str
    attrs: dict[str, str]
    line: int
    col: int
    children: list[_Node] = field(default_factory=list)
    text: str = ""


def _parse_tree(path: Path) -> _Node:
    data = read_input(path, "scene file", SceneError)
    parser = expat.ParserCreate()
    stack: list[_Node] = []
    root: list[_Node] = []

    def start(tag: str, attrs: dict[str, str]) -> None:
        if len(stack) >= MAX_DEPTH:
            raise SceneError(f"elements nested more than {MAX_DEPTH} deep", path, parser.CurrentLineNumber)
        for key, value in attrs.items():
            if len(value) > MAX_ATTRIBUTE:
                raise SceneError(f"<{quoted(tag)[1:-1]}> attribute {quoted(key)} is {len(value):,} characters long "
                                 f"(at most {MAX_ATTRIBUTE:,} accepted)", path, parser.CurrentLineNumber)
        node = _Node(tag, dict(attrs), parser.CurrentLineNumber, parser.CurrentColumnNumber + 1)
        if stack:
            stack[-1].children.append(node)
        else:
            root.append(node)
        stack.append(node)

    def end(tag: str) -> None:
        stack.pop()

    def chars(text: str) -> None:
        if stack and text.strip():
            node = stack[-1]
            if not node.text:
                node.text = text.strip()
                node.attrs.setdefault("__text_line__", str(parser.CurrentLineNumber))

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = chars
    try:
        parser.Parse(data, True)
    except expat.ExpatError as exc:
        raise SceneError(f"malformed XML: {expat.ErrorString(exc.code)}", path, exc.lineno, exc.offset + 1) from None
    if not root:
        raise SceneError("empty scene file: expected a <scene> root element", path)
    return root[0]


def _err(path: Path, node: _Node, message: str) -> SceneError:
    return SceneError(message, path, node.line, node.col)


def _require(path: Path, node: _Node, attr: str) -> str:
    if attr not in node.attrs:
        raise _err(path, node, f"<{node.tag}> requires the attribute '{attr}'")
    return node.attrs[attr]


def _parse_float(path: Path, node: _Node, text: str, what: str) -> float:
    if not _FLOAT_RE.match(text):
        raise _err(path, node, f"{what}: expected a number, got {quoted(text)}")
    return float(text)


def parse_triple(path: Path, node: _Node, text: str, what: str) -> np.ndarray:
    """Parse exactly three numbers separated by commas and/or spaces (spec §2.4)."""
    tokens = [t for t in _SPLIT_RE.split(text.strip()) if t]
    if len(tokens) != 3:
        raise _err(path, node, f"{what}: expected 3 numbers separated by commas or spaces, got {quoted(text)}")
    return np.array([_parse_float(path, node, t, what) for t in tokens])


def _parse_value(path: Path, node: _Node) -> tuple[str, object]:
    kind = node.tag
    name = _require(path, node, "name")
    if kind == "transform":
        return kind, _parse_transform(path, node)
    value = _require(path, node, "value")
    what = f'<{kind} name="{clean(name)}">'
    if kind == "integer":
        if not _INT_RE.match(value):
            raise _err(path, node, f"{what}: expected a base-10 integer, got {quoted(value)}")
        number = int(value)
        if not -INT_LIMIT <= number < INT_LIMIT:
            raise _err(path, node, f"{what}: integer {quoted(value, 30)} is out of range (|value| < 2^63)")
        return kind, number
    if kind == "float":
        return kind, _parse_float(path, node, value, what)
    if kind == "boolean":
        low = value.lower()
        if low not in ("true", "false"):
            raise _err(path, node, f"{what}: expected 'true' or 'false', got {quoted(value)}")
        return kind, low == "true"
    if kind == "string":
        return kind, value
    return kind, parse_triple(path, node, value, what)


def _parse_transform(path: Path, node: _Node) -> tf.Transform:
    m = np.eye(4)
    for op in node.children:
        if op.tag not in TRANSFORM_OPS:
            raise _err(path, op, f"<{op.tag}> is not allowed inside <transform>; expected one of "
                       + ", ".join(f"<{t}>" for t in TRANSFORM_OPS))
        if op.children:
            raise _err(path, op.children[0], f"<{op.tag}> takes no child elements")
        if op.text:
            raise _err(path, op, f"unexpected text content {quoted(op.text, 30)} inside <{op.tag}>; "
                       "its values go in attributes")
        if op.tag == "translate":
            mat = tf.translate(parse_triple(path, op, _require(path, op, "value"), "<translate>"))
        elif op.tag == "scale":
            mat = tf.scale(parse_triple(path, op, _require(path, op, "value"), "<scale>"))
        elif op.tag == "rotate":
            axis = parse_triple(path, op, _require(path, op, "axis"), "<rotate axis>")
            angle = _parse_float(path, op, _require(path, op, "angle"), "<rotate angle>")
            mat = tf.rotate(angle, axis)
        elif op.tag == "matrix":
            text = _require(path, op, "value")
            tokens = [t for t in _SPLIT_RE.split(text.strip()) if t]
            if len(tokens) != 16:
                raise _err(path, op, f"<matrix>: expected 16 numbers (row-major), got {len(tokens)}")
            mat = np.array([_parse_float(path, op, t, "<matrix>") for t in tokens]).reshape(4, 4)
        else:
            o = parse_triple(path, op, _require(path, op, "origin"), "<lookat origin>")
            t = parse_triple(path, op, _require(path, op, "target"), "<lookat target>")
            u = parse_triple(path, op, _require(path, op, "up"), "<lookat up>")
            try:
                mat = tf.lookat(o, t, u)
            except ValueError as exc:
                raise _err(path, op, str(exc)) from None
        m = mat @ m
    if not np.all(np.isfinite(m)) or abs(np.linalg.det(m)) < 1e-300:
        raise _err(path, node, "<transform> is singular or not finite")
    return tf.Transform(m)


def _build(path: Path, node: _Node, is_root: bool) -> ObjectSpec:
    if node.tag not in OBJECT_TAGS:
        raise _err(path, node, f"expected an object tag (<{'>, <'.join(OBJECT_TAGS)}>), got <{node.tag}>")
    if is_root and node.tag != "scene":
        raise _err(path, node, f"the root element must be <scene>, not <{node.tag}>")
    if not is_root and node.tag == "scene":
        raise _err(path, node, "<scene> can only be the root element")
    if node.text:
        raise _err(path, node, f"unexpected text content {quoted(node.text, 30)} inside <{node.tag}>")
    typ = "" if node.tag == "scene" else _require(path, node, "type")
    owner = f'<{node.tag} type="{clean(typ)}">' if typ else f"<{node.tag}>"
    props = PropertyList(owner, str(path), node.line)
    spec = ObjectSpec(node.tag, typ, node.attrs.get("name"), props, [], str(path), node.line)
    for child in node.children:
        if child.tag in PROPERTY_TAGS:
            if child.text:
                raise _err(path, child, f"unexpected text content inside <{child.tag}>")
            if child.tag != "transform" and child.children:
                raise _err(path, child.children[0], f"<{child.tag}> takes no child elements")
            kind, value = _parse_value(path, child)
            name = child.attrs["name"]
            if name in props:
                import warnings

                warnings.warn(f"{path}:{child.line}: duplicate property '{name}', the later value wins",
                              stacklevel=2)
            props.set(name, kind, value, str(path), child.line)
        elif child.tag in TRANSFORM_OPS:
            raise _err(path, child, f"<{child.tag}> must be inside a <transform>")
        else:
            spec.children.append(_build(path, child, False))
    return spec


def parse_scene_file(path: str | Path) -> ObjectSpec:
    """Parse a Nori scene file into its root :class:`ObjectSpec` (the ``<scene>``).

    Raises
    ------
    SceneError
        With file, line and column, for malformed XML, unknown tags, bad attribute values or
        misplaced property/transform tags.
    """
    path = Path(path)
    root = _parse_tree(path)
    return _build(path, root, True)

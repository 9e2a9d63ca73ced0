"""The bad-input catalogue (tests/bad_scenes): a clear error with file and line, exit 2, no traceback,
no output image."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from brdflab.cli.main import main
from brdflab.errors import BrdflabError
from brdflab.scene.loader import load_scene

BAD = Path(__file__).parent / "bad_scenes"
CASES = sorted(BAD.glob("*.xml"))


def _header(path: Path) -> tuple[str, int | None]:
    text = path.read_text(errors="replace")
    expect = re.search(r"<!-- expect: (.*?) -->", text).group(1)
    line = re.search(r"<!-- line: (\d*) -->", text).group(1)
    return expect, int(line) if line else None


@pytest.mark.parametrize("path", CASES, ids=[p.stem for p in CASES])
def test_library_error(path):
    expect, line = _header(path)
    with pytest.raises(BrdflabError) as exc:
        load_scene(path)
    assert re.search(expect, exc.value.message), exc.value.message
    assert exc.value.file is not None
    assert exc.value.line == line


@pytest.mark.parametrize("path", CASES, ids=[p.stem for p in CASES])
def test_cli_error(path, tmp_path, capsys):
    out = tmp_path / "out.exr"
    assert main(["render", str(path), "-o", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("brdflab: error: ") and "Traceback" not in err
    # One short line, with no raw control character from the file (ESC, BEL, NUL are escaped).
    assert err.count("\n") == 1 and len(err) <= 320, err
    assert not re.search(r"[\x00-\x08\x0b-\x1f\x7f]", err), repr(err)
    expect, line = _header(path)
    assert re.search(expect, err)
    if line is not None:
        assert f":{line}" in err
    assert not any(tmp_path.iterdir())


def test_catalogue_is_complete():
    """Every item of the robustness issue's catalogue has at least one file."""
    names = {p.stem for p in CASES}
    for required in ["unclosed_tag", "bad_attribute_syntax", "wrong_root", "unknown_plugin", "unknown_property",
                     "wrong_property_type", "unparsable_number", "triple_wrong_count", "negative_radiance",
                     "fov_zero", "width_zero", "absurd_resolution", "sample_count_zero", "missing_obj",
                     "obj_index_out_of_range", "obj_zero_index", "obj_two_vertex_face", "obj_nonfinite",
                     "zero_area_emitter", "duplicate_camera", "duplicate_integrator", "degenerate_lookat",
                     # Hardening (issue 18): XML attacks, extreme numbers, hostile meshes, leaking messages.
                     "deep_nesting", "huge_attribute", "integer_overflow", "checker_scale_huge",
                     "gaussian_stddev_tiny", "mitchell_nan", "filter_radius_huge", "filter_radius_tiny",
                     "emitter_scale_overflow", "radiance_overflow", "obj_beyond_float32", "transform_beyond_float32",
                     "lookat_text", "obj_index_overflow", "obj_float_overflow", "obj_control_chars", "obj_long_line",
                     "mesh_is_directory", "mesh_name_too_long"]:
        assert required in names

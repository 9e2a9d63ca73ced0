"""``brdflab compare TEST.exr REF.exr``: error metrics of an image against a reference."""

from __future__ import annotations

import argparse
from pathlib import Path

from brdflab.cli.options import add_force_option
from brdflab.errors import BrdflabError, ascii_int, clean
from brdflab.outputs import json_text, prepare_files


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``compare`` sub-command."""
    p = sub.add_parser("compare", help="error metrics of an EXR against a reference EXR",
                       description="MSE, RMSE, relative MSE (mean over pixels and channels of (x−r)²/(r²+0.01)), "
                       "MAPE, the relative bias of the mean and HDR-FLIP (NVIDIA flip-evaluator, exposure range "
                       "from the reference), per channel and overall; non-finite pixels are counted and excluded.")
    p.add_argument("test", type=Path, help="the image to evaluate (EXR)")
    p.add_argument("reference", type=Path, help="the reference image (EXR)")
    p.add_argument("--heatmap", type=Path, metavar="OUT.png",
                   help="write a log-scale error heatmap (.png or .svg; .png is added to a name without suffix)")
    p.add_argument("--signed", type=Path, metavar="OUT.png",
                   help="write a signed false-colour difference map (blue too dark, red too bright; .png or .svg)")
    p.add_argument("--crop", metavar="X,Y,W,H", help="measure only this region (pixels; origin top left)")
    p.add_argument("--no-flip", action="store_true", help="skip HDR-FLIP")
    p.add_argument("--json", action="store_true", help="print the metrics as JSON")
    add_force_option(p, "a --heatmap/--signed file")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Print the metrics (and write the heatmap)."""
    from brdflab.errors import ImageError
    from brdflab.imageio import read_exr
    from brdflab.pages.metrics import compare, crop, flip_error, write_heatmap, write_signed_map

    heatmap, signed = _figure_path(args.heatmap, "--heatmap"), _figure_path(args.signed, "--signed")
    prepare_files([p for p in (heatmap, signed) if p is not None], [args.test, args.reference], args.force,
                  "--heatmap")
    test, ref = read_exr(args.test), read_exr(args.reference)
    try:
        m = compare(test, ref)
        if args.crop:
            box = _box(args.crop)
            test, ref = crop(test, box), crop(ref, box)
            m = compare(test, ref)
        flip = None if args.no_flip else flip_error(test, ref)
    except ImageError as exc:
        raise ImageError(f"{clean(args.test, 100)} vs {clean(args.reference, 100)}: {exc.message}") from None
    title = f"{clean(args.test.name)} vs {clean(args.reference.name)}" + (f", region {args.crop}" if args.crop else "")
    if heatmap is not None:
        write_heatmap(heatmap, test, ref, title=title)
    if signed is not None:
        write_signed_map(signed, test, ref, title=f"signed difference: {title}")
    if args.json:
        d = m.to_dict()
        d["flip"] = flip
        d["crop"] = list(_box(args.crop)) if args.crop else None
        print(json_text(d, indent=2))
    else:
        if args.crop:
            print(f"region {args.crop}")
        print(f"{'':8}{'MSE':>12}{'RMSE':>12}{'relMSE':>12}{'MAPE':>12}{'bias':>10}")
        rows = [("overall", m.mse, m.rmse, m.relmse, m.mape, m.bias)]
        rows += [(c, v["mse"], v["rmse"], v["relmse"], v["mape"], v["bias"]) for c, v in m.per_channel.items()]
        for name, mse, rmse, rel, mape, bias in rows:
            print(f"{name:8}{mse:12.4e}{rmse:12.4e}{rel:12.4e}{mape:12.4e}{100 * bias:+9.3f}%")
        if flip is not None and flip == flip:
            print(f"HDR-FLIP  {flip:.4f}  (mean over pixels; 0 identical, 1 maximal; exposures from the reference)")
        elif flip is not None:
            print("HDR-FLIP  undefined (the reference has no positive luminance to set its exposures)")
        if m.nonfinite:
            print(f"{m.nonfinite} non-finite pixels excluded (of {m.pixels})")
    return 0


def _figure_path(path: Path | None, option: str) -> Path | None:
    """A .png/.svg output name (.png added when there is no suffix)."""
    if path is None:
        return None
    if not path.suffix:
        path = path.with_name(path.name + ".png")
    if path.suffix.lower() not in (".png", ".svg"):
        raise BrdflabError(f"{option} '{clean(path, 100)}': expected a .png or .svg file name")
    return path


def _box(text: str) -> tuple[int, int, int, int]:
    vals = [ascii_int(v, signed=True) for v in text.split(",")]
    if len(vals) != 4 or None in vals:
        raise BrdflabError(f"--crop: expected X,Y,W,H (four integers), got '{clean(text, 40)}'")
    return vals[0], vals[1], vals[2], vals[3]

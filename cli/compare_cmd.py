"""``brdflab compare TEST.exr REF.exr``: error metrics of an image against a reference."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from brdflab.errors import BrdflabError, clean
from brdflab.outputs import check_outputs


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``compare`` sub-command."""
    p = sub.add_parser("compare", help="error metrics of an EXR against a reference EXR",
                       description="MSE, RMSE, relative MSE ((x−r)²/(r²+0.01)), MAPE and the relative bias of the "
                       "mean, per channel and overall; non-finite pixels are counted and excluded.")
    p.add_argument("test", type=Path, help="the image to evaluate (EXR)")
    p.add_argument("reference", type=Path, help="the reference image (EXR)")
    p.add_argument("--heatmap", type=Path, metavar="OUT.png",
                   help="write a log-scale error heatmap (.png or .svg; .png is added to a name without suffix)")
    p.add_argument("--json", action="store_true", help="print the metrics as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Print the metrics (and write the heatmap)."""
    from brdflab.errors import ImageError
    from brdflab.imageio import read_exr
    from brdflab.report.metrics import compare, write_heatmap

    heatmap = args.heatmap
    if heatmap is not None:
        if not heatmap.suffix:
            heatmap = heatmap.with_name(heatmap.name + ".png")
        if heatmap.suffix.lower() not in (".png", ".svg"):
            raise BrdflabError(f"--heatmap '{clean(heatmap, 100)}': expected a .png or .svg file name")
        check_outputs([heatmap], [args.test, args.reference])
    test, ref = read_exr(args.test), read_exr(args.reference)
    try:
        m = compare(test, ref)
    except ImageError as exc:
        raise ImageError(f"{clean(args.test, 100)} vs {clean(args.reference, 100)}: {exc.message}") from None
    if heatmap is not None:
        write_heatmap(heatmap, test, ref, title=f"{clean(args.test.name)} vs {clean(args.reference.name)}")
    if args.json:
        print(json.dumps(m.to_dict(), indent=2))
    else:
        print(f"{'':8}{'MSE':>12}{'RMSE':>12}{'relMSE':>12}{'MAPE':>12}{'bias':>10}")
        rows = [("overall", m.mse, m.rmse, m.relmse, m.mape, m.bias)]
        rows += [(c, v["mse"], v["rmse"], v["relmse"], v["mape"], v["bias"]) for c, v in m.per_channel.items()]
        for name, mse, rmse, rel, mape, bias in rows:
            print(f"{name:8}{mse:12.4e}{rmse:12.4e}{rel:12.4e}{mape:12.4e}{100 * bias:+9.3f}%")
        if m.nonfinite:
            print(f"{m.nonfinite} non-finite pixels excluded (of {m.pixels})")
    return 0

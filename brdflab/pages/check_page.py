"""Outputs of ``brdflab check``: signed block map, difference map, ``check.html`` and ``check.json``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from brdflab.imageio import _atomic_write, write_exr, write_png
from brdflab.outputs import json_text, write_text
from brdflab.pages import page as html

#: The files :func:`write_check` writes into its folder (checked by :func:`brdflab.outputs.prepare_folder`).
CHECK_FILES = ("check.json", "user.png", "brdflab.png", "brdflab.exr", "block_map.png", "z_map.png", "check.html")


def write_block_map(path: Path, user: np.ndarray, result, title: str = "") -> None:
    """The user's image in grey with significantly too dark (blue) / too bright (red) blocks overlaid."""
    import matplotlib

    matplotlib.use("Agg")
    from brdflab.viz.mpl import safe_figures

    safe_figures()  # user text is never mathtext; log axes still read 10⁻²
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    from brdflab.imageio import srgb_bytes

    h, w = user.shape[:2]
    grey = srgb_bytes(user).astype(np.float64).mean(axis=2) / 255.0
    b = result.block
    sm = np.repeat(np.repeat(result.signed_map, b, 0), b, 1)[:h, :w]
    rgba = np.zeros((h, w, 4))
    rgba[sm < 0] = (0.1, 0.35, 1.0, 0.6)
    rgba[sm > 0] = (1.0, 0.15, 0.1, 0.6)
    fig, ax = plt.subplots(figsize=(6.4, 6.4 * h / w + 0.7), dpi=100)
    ax.imshow(grey, cmap="gray", vmin=0, vmax=1)
    ax.imshow(rgba)
    ax.set_axis_off()
    ax.set_title(title or f"blocks ({b}×{b}) significantly different from brdflab's estimate", fontsize=9)
    ax.legend(handles=[Patch(color=(0.1, 0.35, 1.0), label=f"too dark ({result.dark_blocks})"),
                       Patch(color=(1.0, 0.15, 0.1), label=f"too bright ({result.bright_blocks})")],
              loc="lower right", fontsize=8)
    fig.tight_layout()
    _atomic_write(path, lambda tmp: fig.savefig(tmp, format=str(path).rsplit(".", 1)[-1]))
    plt.close(fig)


def write_z_map(path: Path, result) -> None:
    """Block z-scores (user − brdflab)/sd on a diverging scale (blue darker, red brighter)."""
    import matplotlib

    matplotlib.use("Agg")
    from brdflab.viz.mpl import safe_figures

    safe_figures()  # user text is never mathtext; log axes still read 10⁻²
    import matplotlib.pyplot as plt

    z = result.z_map
    lim = max(4.0, float(np.nanpercentile(np.abs(z), 99)) if z.size else 4.0)
    fig, ax = plt.subplots(figsize=(6.4, 6.4 * z.shape[0] / max(z.shape[1], 1) + 0.7), dpi=100)
    im = ax.imshow(z, cmap="RdBu_r", vmin=-lim, vmax=lim, interpolation="nearest")
    ax.set_axis_off()
    ax.set_title("block t-statistic of the most significant channel", fontsize=9)
    fig.colorbar(im, ax=ax, fraction=0.046, pad=0.02, label="t  (negative: too dark)")
    fig.tight_layout()
    _atomic_write(path, lambda tmp: fig.savefig(tmp, format="png"))
    plt.close(fig)


def write_check(out: Path, user_paths: list[Path], user: list[np.ndarray], result, scene: Path,
                attribution: dict | None = None) -> Path:
    """Write ``check.json``, the images, maps and ``check.html`` into ``out``; return the page path.
    ``attribution``: the where-and-what of :func:`brdflab.stats.attribution.attribute` (if any)."""
    out.mkdir(parents=True, exist_ok=True)
    d = result.to_dict()
    d.update({"scene": str(scene), "renders": [str(p) for p in user_paths]})
    if attribution is not None:
        d["attribution"] = attribution
    write_text(out / "check.json", json_text(d, indent=2))
    mean_user = np.mean(np.stack(user), axis=0)
    write_png(out / "user.png", mean_user)
    write_png(out / "brdflab.png", result.estimate)
    write_exr(out / "brdflab.exr", result.estimate, extra={"brdflab_runs": str(result.reference_runs),
                                                          "brdflab_spp": str(result.reference_spp)})
    write_block_map(out / "block_map.png", mean_user, result)
    write_z_map(out / "z_map.png", result)
    rows = [["verdict", "consistent" if result.consistent else "biased"],
            ["p-value (family-wise)", f"{result.p_value:.3g}"],
            ["relative bias of the image mean", f"{100 * result.bias:+.3f} %"],
            ["99 % interval", f"{100 * result.bias_ci[0]:+.3f} … {100 * result.bias_ci[1]:+.3f} %"],
            ["image-mean test p", f"{result.bias_p:.3g}"],
            ["blocks too dark / too bright / total",
             f"{result.dark_blocks} / {result.bright_blocks} / {result.blocks}"],
            ["smallest detectable mean bias (80 % power)", f"{100 * result.min_detectable_bias:.2g} %"],
            ["smallest detectable bias of one block (median)", f"{100 * result.min_detectable_block_bias:.2g} %"],
            ["variance method", result.method],
            ["block sizes tested", ", ".join(f"{b}×{b}" for b in (result.scales or [result.block])) + " px"],
            ["false-alarm level α", f"{result.alpha}"],
            ["spatial correlation factor F", f"{result.correlation_factor:.2f}"],
            ["user renders", str(result.user_renders)],
            ["brdflab estimate", result.reference_label],
            ["seconds", f"{result.seconds:.1f}"]]
    if result.nonfinite:
        rows.append(["non-finite pixels excluded", str(result.nonfinite)])
    flagged = [[f["x"], f["y"], f["w"], f["h"], f["channel"], f["sign"], f"{f['t']:+.2f}", f"{f['p_adjusted']:.2g}",
                "" if f["relative_difference"] is None else f"{100 * f['relative_difference']:+.1f} %"]
               for f in sorted(result.flagged, key=lambda f: f["p_adjusted"])[:200]]
    body = html.section("Verdict", html.esc_p(result.verdict()) + html.table(["quantity", "value"], rows))
    body += html.section("Images — click to zoom all", html.image_row(
        [(out / "user.png", "your render" + (f" (mean of {len(user)})" if len(user) > 1 else "")),
         (out / "brdflab.png", "brdflab's estimate"), (out / "block_map.png", "significant blocks")]))
    if attribution is not None:

        body += html.section("Where and what", attribution_section(attribution))
    body += html.section("Block statistics", html.image_row([(out / "z_map.png", "signed block t-map")], cls="plot"))
    if flagged:
        body += html.section(f"Flagged blocks ({len(result.flagged)}, most significant first)", html.table(
            ["x", "y", "w", "h", "channel", "direction", "t", "adjusted p", "difference"], flagged))
    body += html.section("Method", html.esc_p(
        "Block means of your render and of brdflab's independent estimate are compared per channel with a t-test; "
        "the block tests share α/2 by Holm's step-down procedure and the whole-image mean test gets α/2, so the "
        "chance of calling an unbiased render biased is at most α. See brdflab/stats/render_check.py."))
    path = out / "check.html"
    write_text(path, html.page(f"brdflab check — {scene.name}", body))
    return path


def attribution_section(att: dict) -> str:
    """HTML body of the check page's "Where and what" section: one row per region (whole image first)."""
    from brdflab.stats.findings import _fits_text

    def row(label: str, r: dict) -> list[str]:
        rel = "" if r.get("relative_difference") is None else f"{100 * r['relative_difference']:+.1f} %"
        mats = "; ".join(f"{m['name']} {100 * m['share']:.0f} %"
                         + ("" if m.get("relative_difference") is None else
                            f" (difference {100 * m['relative_difference']:+.1f} %)") for m in r["materials"])
        ems = ", ".join(f"{e['name']} {100 * e['share']:.0f} %" for e in r["emitters"])
        return [label, rel, mats, ems, _fits_text(r), r["finding"]]

    rows = [row("whole image", att["whole_image"])]
    for i, r in enumerate(att["regions"], 1):
        rows.append(row(f"region {i}: {r['sign']}, {r['blocks']} blocks at x {r['x']}…{r['x'] + r['w']}, "
                        f"y {r['y']}…{r['y'] + r['h']}", r))
    intro = html.esc_p(
        f"Auxiliary renders of the scene ({att['aux_spp']} spp): the material each pixel shows, the direct light of "
        "each emitter, and brdflab's direct light split into its emitter-sampled part E and BSDF-sampled part B "
        "(MIS-weighted halves of direct_mis). The difference d = yours − brdflab's (mean of R, G, B) is fitted as "
        f"d ≈ a·E + b·B over cells of {att['cell']}×{att['cell']} pixels (HC3 standard errors); a coefficient is "
        f"significant at p ≤ {att['level']}. "
        + ("For this path-traced scene also d ≈ a·D + b·I, with D and I brdflab's direct and indirect light "
           "(path_mis split by path length: at most two segments, and the longer paths), so b is the relative error "
           "of your indirect light. " if "depth_fit" in att["whole_image"] else "")
        + "Descriptive: not part of the verdict. See brdflab/stats/attribution.py.")
    return intro + html.table(["where", "difference", "materials (pixel share)", "emitters (share of the light)",
                               "fit", "finding"], rows)

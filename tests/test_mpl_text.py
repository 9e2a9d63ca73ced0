"""Figures: user text with a ``$`` is never mathtext, and log axes and colour bars still label decades
readably (10⁻², not ``$\\mathdefault{10^{-2}}$``)."""

from __future__ import annotations

import numpy as np

from brdflab.viz.mpl import plain_label, safe_figures


def test_plain_labels():
    assert plain_label(r"$\mathdefault{10^{-2}}$") == "10⁻²"
    assert plain_label(r"$\mathdefault{2\times10^{-3}}$") == "2×10⁻³"
    assert plain_label(r"$\mathdefault{10^{0}}$") == "10⁰"
    assert plain_label("") == "" and plain_label("0.5") == "0.5"


def test_log_ticks_and_dollar_titles_draw(tmp_path):
    safe_figures()
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    fig, ax = plt.subplots()
    im = ax.imshow(np.logspace(-6, 2, 64).reshape(8, 8), norm=LogNorm())
    cb = fig.colorbar(im)
    ax.set_yscale("log")
    ax.set_title("my $BSDF_v2$ file_$x.exr")  # a user's name with dollars: plain text, no crash
    fig.savefig(tmp_path / "f.png")
    labels = [t.get_text() for t in cb.ax.get_yticklabels()] + [t.get_text() for t in ax.get_yticklabels()]
    plt.close(fig)
    assert labels and not any("$" in s or "mathdefault" in s for s in labels), labels
    assert any("10" in s for s in labels)

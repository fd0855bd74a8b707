"""omni_app.figures.save_png: figures laid out and drawn once, cropped to their ink, never
clipped (a label longer than the room falls back to matplotlib's tight_layout)."""

import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
from PIL import Image  # noqa: E402  (matplotlib's own PNG writer)

from omni_app import figures as F  # noqa: E402


def _ink(path):
    img = np.asarray(Image.open(path).convert("RGB")).astype(int)
    return img, (img != 255).any(axis=2)


def _figure(ylabel="y", title="title", ncols=2, scale=1.0):
    fig, axes = plt.subplots(1, ncols, figsize=(10, 4))
    for ax in np.atleast_1d(axes):
        ax.plot(np.linspace(0, 1, 50), scale * np.linspace(0, 1, 50) ** 2, "o-", label="data")
        ax.set(xlabel="x [s]", ylabel=ylabel, title=title)
        ax.legend()
    return fig


def test_cropped_to_the_ink_with_a_white_border(tmp_path):
    """A figure whose labels fit the room: drawn once and cropped, with PAD_IN of white on
    every side (so nothing touches the edge) and about the nominal size."""
    path = tmp_path / "f.png"
    F.save_png(_figure(), path, dpi=100)
    img, ink = _ink(path)
    pad = int(round(F.PAD_IN * 100))
    rows, cols = np.flatnonzero(ink.any(axis=1)), np.flatnonzero(ink.any(axis=0))
    assert rows[0] == pad and cols[0] == pad
    assert img.shape[0] - 1 - rows[-1] == pad and img.shape[1] - 1 - cols[-1] == pad
    # about the nominal 10 x 4 in (the axes keep their tight_layout size)
    assert abs(img.shape[1] - 1000) < 120 and abs(img.shape[0] - 400) < 60


@pytest.mark.parametrize("ylabel, scale", [("y" * 10, 1.0), ("y", 1.2345678e-7), ("y", 1e9)])
def test_other_data_is_not_clipped(tmp_path, ylabel, scale):
    """Tick labels of other magnitudes and longer labels: still cropped with a white border
    (the room holds them), nothing on the edge."""
    path = tmp_path / "f.png"
    F.save_png(_figure(ylabel=ylabel, scale=scale), path, dpi=100)
    _, ink = _ink(path)
    assert not (ink[0].any() or ink[-1].any() or ink[:, 0].any() or ink[:, -1].any())


def test_a_label_longer_than_the_room_falls_back_to_tight_layout(tmp_path):
    """A title far wider than its axes reaches the edge: the figure is laid out by
    tight_layout and saved at its nominal size instead of a clipped crop."""
    path = tmp_path / "f.png"
    F.save_png(_figure(title="a very long title " * 8, ncols=1), path, dpi=100)
    img, _ = _ink(path)
    assert img.shape[:2] == (400, 1000)


def test_same_figure_same_bytes(tmp_path):
    F.save_png(_figure(), tmp_path / "a.png")
    F.save_png(_figure(), tmp_path / "b.png")
    assert (tmp_path / "a.png").read_bytes() == (tmp_path / "b.png").read_bytes()


def test_closes_the_figure(tmp_path):
    fig = _figure()
    F.save_png(fig, tmp_path / "f.png")
    assert not plt.fignum_exists(fig.number)

"""Every figure reads cleanly: rendered, no two texts overlap and none leaves the canvas.

The texts are matplotlib's own: titles, axis labels, annotations and the tick labels each
axis draws, measured by the renderer (Text.get_window_extent) after a full draw. The check
is shown to fail on layouts like the ones issue 17 saw (texts on top of each other, a label
cut off at the edge).
"""

from __future__ import annotations

import dataclasses
import itertools
import json
from pathlib import Path

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.text import Text  # noqa: E402

from drake_continuum.kinematics.arm import MODELS_DIR, ArmConfig, load_arm  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
# Curled around the mug body (as in test_viz.py), touching it.
WRAP = ArmConfig([0.1402, 0.1373, 0.1373], [4.408, 19.42, 19.42],
                 [-np.pi / 2, np.pi / 2, np.pi / 2])


def drawn_texts(fig):
    """(text, pixel bbox) of every non-empty text the figure draws."""
    owned, shown = set(), []
    for ax in fig.axes:
        axes_on = getattr(ax, "_axis3don", ax.axison)  # Axes3D draws its own axes
        for axis in ax._axis_map.values():
            ticks = axis.get_major_ticks() + axis.get_minor_ticks()
            owned.update(lab for t in ticks for lab in (t.label1, t.label2))
            owned.update((axis.label, axis.offsetText))
            if axes_on and axis.get_visible():
                # The ticks the axis draws (those in its view interval), asked before the
                # draw: asking resets a 3-D label to its 2-D place.
                shown += [lab for t in axis._update_ticks() for lab in (t.label1, t.label2)]
                shown += [axis.label, axis.offsetText]
    shown += [t for t in fig.findobj(Text) if t not in owned]
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    return [(t, t.get_window_extent(renderer)) for t in shown
            if t.get_visible() and t.get_text().strip()]


def layout_problems(fig, slack: float = 1.0) -> list[str]:
    """Texts that overlap another by more than `slack` pixels each way, or leave the canvas."""
    width, height = fig.canvas.get_width_height()
    texts = drawn_texts(fig)
    problems = [f"outside the canvas: {t.get_text()!r} at {np.round(b.bounds)}"
                for t, b in texts if b.x0 < -slack or b.y0 < -slack
                or b.x1 > width + slack or b.y1 > height + slack]
    for (t1, b1), (t2, b2) in itertools.combinations(texts, 2):
        if (min(b1.x1, b2.x1) - max(b1.x0, b2.x0) > slack
                and min(b1.y1, b2.y1) - max(b1.y0, b2.y0) > slack):
            problems.append(f"overlap: {t1.get_text()!r} and {t2.get_text()!r}")
    return problems


def check(fig):
    try:
        problems = layout_problems(fig)
    finally:
        plt.close(fig)
    assert not problems, "\n".join(problems[:10])


# ----------------------------------------------------------------- the check itself

def test_the_check_sees_overlaps_clipping_and_crowded_3d_ticks():
    fig = plt.figure(figsize=(4, 3), dpi=100)
    fig.text(0.5, 0.5, "one label")
    fig.text(0.52, 0.5, "another label")
    assert any(p.startswith("overlap") for p in layout_problems(fig))
    plt.close(fig)

    fig = plt.figure(figsize=(4, 3), dpi=100)
    fig.text(0.98, 0.5, "cut off at the right")
    assert any(p.startswith("outside") for p in layout_problems(fig))
    plt.close(fig)

    # The old Fig. 5 cell: a 3-D axes with every tick labelled, titles of the row below on
    # the tick labels of the row above, the right-hand cell cut off.
    fig = plt.figure(figsize=(4, 4), dpi=100)
    for k in range(4):
        ax = fig.add_subplot(2, 2, k + 1, projection="3d")
        ax.plot([-0.15, 0.05], [-0.1, 0.1], [-0.05, 0.15])
        ax.set_xlabel("x (m)")
        ax.set_title("toilet_paper_000: 54% near", fontsize=9)
    fig.subplots_adjust(left=0, right=1, bottom=0, top=0.95, wspace=0, hspace=0.05)
    problems = layout_problems(fig)
    plt.close(fig)
    assert any(p.startswith("overlap") for p in problems)
    assert any(p.startswith("outside") for p in problems)

    fig = plt.figure(figsize=(4, 3), dpi=100, layout="constrained")
    fig.add_subplot().set_title("a clean figure")
    assert layout_problems(fig) == []
    plt.close(fig)


# ----------------------------------------------------------------- the figures

@pytest.fixture(scope="module")
def mug_cell():
    from drake_continuum.wrapping.scene import WrapScene
    arm = load_arm()
    scene = WrapScene(arm, MODELS_DIR / "mug.obj")
    scene.set_config(WRAP)
    return dict(mesh=scene.object_trimesh, arm=arm, config=WRAP, contacts=scene.contacts())


@pytest.mark.parametrize("n, ncols", [(1, 4), (3, 2), (8, 4), (10, 5)])
def test_fig5_grid_reads_cleanly_whatever_the_grid(mug_cell, n, ncols):
    from drake_continuum.viz.plots import wraps_grid_figure
    items = [{**mug_cell, "title": f"toilet_paper_00{k}: 54% near"} for k in range(n)]
    check(wraps_grid_figure(items, ncols=ncols))


@pytest.mark.parametrize("size", [(800, 800), (640, 480)])
def test_one_wrap_picture_reads_cleanly(mug_cell, size):
    from drake_continuum.viz.plots import wrap_figure
    check(wrap_figure(mug_cell["mesh"], mug_cell["arm"], WRAP, contacts=mug_cell["contacts"],
                      size_px=size))


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    from drake_continuum.objects.dataset import generate_dataset, load_manifest
    out = tmp_path_factory.mktemp("objects")
    generate_dataset(out, seed=0, counts={"apple": 2, "bottle": 2, "bowl": 2, "mug": 1},
                     workers=1, progress=False)
    return load_manifest(out)


@pytest.mark.parametrize("n", [1, 3, 7])
def test_object_gallery_reads_cleanly_with_few_objects(dataset, n):
    from drake_continuum.objects.gallery import gallery_figure
    check(gallery_figure(dataclasses.replace(dataset, objects=dataset.objects[:n])))


def test_fig8_reads_cleanly_and_says_the_cloud_is_simulated():
    from pydrake.math import RollPitchYaw

    from drake_continuum.objects.mesh import load_mesh
    from drake_continuum.perception.cloud import load_cloud
    from drake_continuum.perception.comparison import SIMULATED_NOTE, fig8_figure
    from drake_continuum.perception.fitting import fit_cloud
    meta = json.loads((ROOT / "real" / "data" / "cylinder_0.json").read_text())
    arm = load_arm().with_base(np.asarray(meta["base_position"], float),
                               RollPitchYaw(meta["base_rpy"]).ToRotationMatrix().matrix())
    cloud = load_cloud(ROOT / "real" / "data" / "cylinder_0.pcd")
    seg, fit = fit_cloud(cloud, arm, ArmConfig.from_dict(meta["config"]).s)
    fig = fig8_figure(cloud, seg, fit, arm, load_mesh(ROOT / "real" / "data" / "cylinder.obj"),
                      title="cylinder_0.pcd: deviation mean 0.9 mm, Hausdorff 6.7 mm")
    assert SIMULATED_NOTE in fig.get_suptitle()
    assert all(ax.get_zlabel() == "z (m)" for ax in fig.axes)
    check(fig)


def test_a_cloud_is_simulated_by_its_sidecar(tmp_path):
    from drake_continuum.perception.comparison import simulated_cloud
    cloud = tmp_path / "capture.pcd"
    cloud.write_text("not read")
    assert not simulated_cloud(cloud)  # no sidecar: a real capture
    cloud.with_suffix(".json").write_text(json.dumps({"base_position": [0, 0, 0.05]}))
    assert not simulated_cloud(cloud)
    cloud.with_suffix(".json").write_text(json.dumps({"capture": "simulated"}))
    assert simulated_cloud(cloud)
    assert simulated_cloud(ROOT / "real" / "data" / "mug_0.pcd")  # the simulator's sensor

"""Pictures: a StaticHtml Meshcat page of an animated wrap renders in real headless Chromium
(no console errors, a non-blank canvas, its title, legend and playback controls), contacts are
drawn outside the arm's tube, and plot_wrap writes a PNG of the asked size."""

from __future__ import annotations

import io
import os

import numpy as np
import pytest

from drake_continuum.kinematics.arm import MODELS_DIR, ArmConfig, load_arm
from drake_continuum.viz.meshcat import contact_pins, save_html, show_wrap
from drake_continuum.viz.plots import plot_wrap, plot_wraps_grid
from drake_continuum.wrapping.scene import WrapScene

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
                 "--disable-background-networking", "--disable-component-update",
                 "--no-first-run"]
MUG = MODELS_DIR / "mug.obj"
# Curled around the mug body at its base's height, touching it (see the demo command).
WRAP = ArmConfig([0.1402, 0.1373, 0.1373], [4.408, 19.42, 19.42],
                 [-np.pi / 2, np.pi / 2, np.pi / 2])


def _trajectory(n=12):
    """From the first section's bend alone to the full curl (the arm clear of the mug)."""
    return [ArmConfig(WRAP.s, WRAP.kappa * [1.0, a, a], WRAP.phi) for a in np.linspace(0.6, 1, n)]


@pytest.fixture(scope="module")
def arm():
    return load_arm()


@pytest.mark.skipif(not os.path.exists(CHROMIUM),
                    reason=f"{CHROMIUM} is absent (apt-get install -y chromium; "
                           "scripts/setup.sh installs it)")
def test_static_html_renders_in_headless_chromium(arm, tmp_path):
    sync_playwright = pytest.importorskip("playwright.sync_api").sync_playwright
    meshcat, scene = show_wrap(arm, MUG, _trajectory(),
                                   chords=(np.array([[-0.06, 0, 0.05]]),
                                           np.array([[0.02, 0, 0.05]])))
    assert len(scene.contacts()) > 0
    title = "mug, plane 3: complete, 11 contacts"
    page_path = save_html(meshcat, tmp_path / "wrap.html", title=title, chords=True)
    html = page_path.read_text()
    assert "<html" in html.lower() and len(html) > 10_000

    errors = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 800, "height": 600})
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(page_path.as_uri(), wait_until="load")
            page.wait_for_selector("canvas", timeout=30_000)
            page.wait_for_timeout(1500)  # let the render loop draw a few frames
            png = page.screenshot()
            tab, overlay = page.title(), page.inner_text("#wrap-overlay")
            # Meshcat's controls, with the recording's play button, are still there
            controls = [page.locator(f"text={t}").count() for t in
                        ("Open Controls", "Animations", "play")]
        finally:
            browser.close()
    assert not errors, f"console errors: {errors}"
    assert tab == title and overlay.startswith(title)
    assert "arm" in overlay and "contact" in overlay and "chords" in overlay
    assert all(controls), controls

    from PIL import Image
    pixels = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=float)
    assert pixels.shape[:2] == (600, 800)
    # Not blank, and the scene is in it: the background is a grey gradient, so count the
    # arm's orange pixels.
    r, g, b = pixels[..., 0], pixels[..., 1], pixels[..., 2]
    orange = (r > 180) & (g > 60) & (g < 190) & (b < 90)
    assert orange.mean() > 0.005, f"no arm drawn ({orange.mean():.4f} of pixels orange)"
    assert len(np.unique(pixels.reshape(-1, 3).astype(int), axis=0)) > 50


def test_show_wrap_prints_nothing(arm, capsys):
    """A library call leaves stdout to its caller (a --json command prints one document)."""
    meshcat, _ = show_wrap(arm, MUG, _trajectory()[:2])
    assert capsys.readouterr().out == ""
    assert meshcat.web_url().startswith("http://")


def test_contact_pins_stand_outside_the_tube(arm):
    """A contact lies on the tube's surface, so a marker there is hidden inside the drawn
    arm; each pin's head is outside it (farther from the centre line than the radius)."""
    scene = WrapScene(arm, MUG)
    scene.set_config(WRAP)
    contacts = scene.contacts()
    assert len(contacts) >= 3
    centre = arm.backbone(WRAP, n=2000).position
    start, head = contact_pins(contacts, arm.radius, head_radius=0.003)
    to_axis = lambda q: np.linalg.norm(q[:, None] - centre[None], axis=2).min(axis=1)  # noqa
    assert np.all(to_axis(start) < arm.radius + 0.003)  # the contacts: on the tube
    assert np.all(to_axis(head) > arm.radius + 0.003)  # the heads: clear of it
    assert np.allclose(np.linalg.norm(head - start, axis=1), 2 * arm.radius + 0.007)


def test_plot_wrap_writes_png_of_the_asked_size(arm, tmp_path):
    scene = WrapScene(arm, MUG)
    scene.set_config(WRAP)
    contacts = scene.contacts()
    path = plot_wrap(scene.object_trimesh, arm, WRAP, contacts=contacts, path=tmp_path / "wrap.png",
                         size_px=(640, 480))
    from PIL import Image
    with Image.open(path) as im:
        assert im.size == (640, 480) and im.format == "PNG"
        pixels = np.asarray(im.convert("RGB"), dtype=float)
    assert pixels.std() > 5  # something was drawn
    assert not list(tmp_path.glob("*.tmp*"))  # written atomically


def test_plot_wraps_grid(arm, tmp_path):
    scene = WrapScene(arm, MUG)
    scene.set_config(WRAP)
    item = dict(mesh=scene.object_trimesh, arm=arm, config=WRAP, contacts=scene.contacts())
    path = plot_wraps_grid([item, {**item, "title": "mug"}, {**item, "contacts": None}],
                               tmp_path / "grid.png", ncols=2, cell_px=200)
    from PIL import Image
    with Image.open(path) as im:
        assert im.size == (400, 400)


def test_demo_command_prints_contacts_and_draws_them(tmp_path, capsys):
    from drake_continuum.cli import main
    assert main(["demo", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "contacts (sections numbered from 1" in out
    lines = [ln for ln in out.splitlines() if ln[:2].strip().isdigit() and len(ln.split()) == 10]
    assert len(lines) >= 3
    assert {ln.split()[1] for ln in lines} <= {"1", "2", "3"}
    assert (tmp_path / "demo.png").stat().st_size > 10_000

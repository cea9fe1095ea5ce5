"""meshrec.figures.viz and ``meshrec show``: off-screen open3d pictures, checked pixel by pixel.

These tests render for real (open3d's OffscreenRenderer on Mesa's lavapipe in CI, no
display): the PNG has the requested size, is not blank, and shows the curve colours where
the contact projects.
"""

import json
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest
from matplotlib import image as mpimg

import meshrec
from meshrec.app.cli import main
from meshrec.figures import viz
from meshrec.registration.transform import apply_transform


def _read_png(path: Path) -> np.ndarray:
    """(h, w, 3) uint8 pixels of a PNG."""
    img = mpimg.imread(str(path))
    return np.round(img[..., :3] * 255.0).astype(np.int64)


def _near(img: np.ndarray, xy, color, radius: float, tol: int = 40) -> int:
    """How many pixels within ``radius`` of ``xy`` are within ``tol`` of ``color``."""
    h, w, _ = img.shape
    yy, xx = np.mgrid[0:h, 0:w]
    disc = (xx - xy[0]) ** 2 + (yy - xy[1]) ** 2 <= radius**2
    target = np.round(np.asarray(color) * 255.0)
    close = np.all(np.abs(img - target) <= tol, axis=2)
    return int(np.count_nonzero(close & disc))


@pytest.fixture(scope="module")
def setup(touched_ellipsoid):
    return touched_ellipsoid


@pytest.fixture(scope="module")
def snapshot(setup, tmp_path_factory):
    out = tmp_path_factory.mktemp("render") / "pic.png"
    return viz.render(setup.rec, out, truth=setup.sim, size=(320, 240))


# ------------------------------------------------------------------ the picture itself
def test_registration_is_at_the_truth(setup):
    # The premise of the colour checks below: registered and true curves overlap.
    best = setup.rec.best
    assert best.model == "ellipsoid"
    assert np.linalg.norm(best.contact - setup.sim.contact) < 0.02


def test_render_writes_png_of_requested_size(snapshot):
    img = _read_png(snapshot.path)
    assert img.shape == (240, 320, 3)
    assert snapshot.size == (320, 240)
    assert np.array_equal(img, snapshot.image.astype(np.int64))


def test_render_is_not_blank(snapshot):
    img = snapshot.image.astype(np.int64)
    background = np.all(img >= 250, axis=2)
    assert background.mean() < 0.98  # the model fills part of the picture, or all of it
    assert img.std() > 20
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 50


def test_curve_colours_near_projected_contact(setup, snapshot):
    img = snapshot.image.astype(np.int64)
    xy = snapshot.project(setup.rec.best.contact)[0]
    assert np.allclose(xy, [160, 120], atol=2)  # the camera looks at the contact
    for key in ("registered", "truth", "contact"):
        assert _near(img, xy, viz.COLORS[key], radius=40) >= 10, key
    # The registered curves, not just the marker: their colour along the whole curves.
    ends = np.array([c[[0, -1]] for c in setup.sim.touch.curves]).reshape(-1, 3)
    ends = apply_transform(setup.rec.best.T_model_touch, ends)
    for e in snapshot.project(ends):
        assert _near(img, e, viz.COLORS["registered"], radius=12) >= 3
    # Far from everything drawn (a corner), no curve colour.
    assert _near(img, (0, 0), viz.COLORS["registered"], radius=20) == 0


@pytest.mark.slow
def test_render_without_path_returns_image_only(setup):
    snap = viz.render(setup.rec.best, touch=setup.sim.touch, size=(64, 48), view="model")
    assert snap.path is None
    assert snap.image.shape == (48, 64, 3)
    xy = snap.project(setup.sim.contact)[0]
    assert 0 <= xy[0] < 64
    assert 0 <= xy[1] < 48


@pytest.mark.slow
def test_many_sizes_in_one_process_then_a_clean_exit(setup, tmp_path):
    # open3d 0.20 aborts a process that destroys a second OffscreenRenderer and hangs on
    # a third: each picture is drawn in a child process, so a caller may render many
    # sizes and still exit with status 0.
    code = (
        "import sys, meshrec\n"
        "from meshrec.figures import viz\n"
        f"lib = meshrec.ModelLibrary.from_folder({str(setup.folder)!r}, "
        f"cache_dir={str(setup.cache)!r})\n"
        f"sim = meshrec.simulate_touch(lib['ellipsoid'], rng={setup.seed})\n"
        "rec = meshrec.recognize(sim.touch, lib)\n"
        "for size in [(64, 48), (32, 24), (48, 48)]:\n"
        "    assert viz.render(rec, size=size).image.shape == (size[1], size[0], 3)\n"
        "print('rendered')\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "rendered" in proc.stdout


def test_render_child_failure_and_timeout_raise_render_error(setup, monkeypatch):
    monkeypatch.setattr(viz.sys, "executable", "false")  # the child exits with status 1
    with pytest.raises(viz.RenderError, match="exit status 1"):
        viz.render(setup.rec, size=(32, 24))
    monkeypatch.undo()
    monkeypatch.setattr(viz, "_RENDER_TIMEOUT", 1e-3)
    with pytest.raises(viz.RenderError, match="took more than"):
        viz.render(setup.rec, size=(32, 24))


@pytest.mark.slow
def test_cli_show_screenshot(setup, tmp_path, capsys):
    out = tmp_path / "shots" / "show.png"
    code = main(
        [
            "show",
            str(setup.files / "touch.csv"),
            "--models",
            str(setup.folder),
            "--cache-dir",
            str(setup.cache),
            "--truth",
            str(setup.files / "truth.json"),
            "--screenshot",
            str(out),
            "--size",
            "200x150",
        ]
    )
    assert code == 0
    assert "wrote" in capsys.readouterr().out
    img = _read_png(out)
    assert img.shape == (150, 200, 3)
    assert _near(img, (100, 75), viz.COLORS["registered"], radius=30) >= 10
    assert _near(img, (100, 75), viz.COLORS["truth"], radius=30) >= 10


def test_show_passes_scene_to_open3d(setup, monkeypatch):
    o3d = viz.check_offscreen()
    seen = {}
    monkeypatch.setattr(o3d.visualization, "draw", lambda items, **kw: seen.update(kw, n=items))
    monkeypatch.setenv("DISPLAY", ":99")
    viz.show(setup.rec, truth=setup.sim, size=(300, 200))
    names = {item["name"] for item in seen["n"]}
    assert {"model", "registered_curves", "truth_curves", "contact", "candidates"} <= names
    assert seen["width"] == 300
    assert np.allclose(seen["lookat"], setup.rec.best.contact)


# ------------------------------------------------------------------ errors
def test_show_without_display_raises(setup, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(ValueError, match="display"):
        viz.show(setup.rec)
    code = main(["show", str(setup.files / "touch.csv"), "--models", str(setup.folder)])
    assert code == 2


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"size": (10, 10)}, "size must be"),
        ({"size": (100.5, 100)}, "size must be"),
        ({"size": "big"}, "size must be"),
        ({"view": "top"}, "view must be"),
        ({"model": "teapot"}, "model must be one of"),
        ({"touch": "touch.csv"}, "touch must be a TouchData"),
        ({"mesh": 42}, "mesh must be"),
        ({"truth": 42}, "truth must be"),
        ({"truth": {"contact": [0, 0, 0]}}, "T_model_touch"),
        ({"truth": {"T_model_touch": [[1, 0], [0, 1]]}}, "4x4"),
        ({"truth": {"T_model_touch": "eye"}}, "4x4"),
    ],
)
def test_render_rejects_bad_arguments(setup, kwargs, match):
    with pytest.raises(ValueError, match=match):
        viz.render(setup.rec, **kwargs)


def test_render_rejects_bad_inputs(setup, tmp_path):
    with pytest.raises(ValueError, match=r"path must end in \.png"):
        viz.render(setup.rec, tmp_path / "pic.jpg")
    with pytest.raises(ValueError, match="result must be a Recognition or a Registration"):
        viz.render("result")
    with pytest.raises(ValueError, match="touch must be given"):
        viz.render(setup.rec.best)
    with pytest.raises(ValueError, match="model must be 'ellipsoid'"):
        viz.render(setup.rec.best, touch=setup.sim.touch, model="other")
    with pytest.raises(ValueError, match="cannot be read"):
        viz.render(setup.rec, truth=tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json", encoding="utf-8")
    with pytest.raises(ValueError, match="is not JSON"):
        viz.render(setup.rec, truth=bad)


def test_render_rejects_rejected_models(setup):
    rejected = meshrec.Registration(
        model="flat", path="flat.stl", error=None, contact=None, normal=None, phi=None,
        T_model_touch=None, candidates=0, raw_hits=0, searches=0, seconds=0.0,
        reason="no vertex matches",
    )  # fmt: skip
    with pytest.raises(ValueError, match="rejected by the table lookup"):
        viz.render(rejected, touch=setup.sim.touch)
    none_recognised = meshrec.Recognition(
        touch=setup.sim.touch, geometry=setup.rec.geometry, ranking=(rejected,), seconds=0.0
    )
    with pytest.raises(ValueError, match="every model rejected"):
        viz.render(none_recognised)


@pytest.mark.slow
def test_truth_for_another_model_warns(setup):
    truth = dict(setup.sim.truth_dict(), model="banana")
    with pytest.warns(UserWarning, match="truth is for model 'banana'"):
        snap = viz.render(setup.rec, truth=truth, size=(32, 24))
    assert snap.image.shape == (24, 32, 3)


def test_project_rejects_bad_shape(snapshot):
    with pytest.raises(ValueError, match="points must be"):
        snapshot.project(np.zeros((2, 2)))


def _fake_import(exc):
    def import_module(name):
        raise exc

    return types.SimpleNamespace(import_module=import_module)


def test_missing_open3d_names_pip_package(monkeypatch):
    exc = ModuleNotFoundError("No module named 'open3d'", name="open3d")
    monkeypatch.setattr(viz, "importlib", _fake_import(exc))
    with pytest.raises(viz.VizDependencyError, match=r"open3d is not installed: pip install"):
        viz.check_offscreen()


def test_missing_system_library_names_debian_package(monkeypatch):
    exc = ImportError("libusb-1.0.so.0: cannot open shared object file: No such file")
    monkeypatch.setattr(viz, "importlib", _fake_import(exc))
    with pytest.raises(viz.VizDependencyError, match=r"apt-get install libusb-1.0-0"):
        viz.check_offscreen()
    exc = OSError("libfoo.so.3: cannot open shared object file")
    monkeypatch.setattr(viz, "importlib", _fake_import(exc))
    with pytest.raises(viz.VizDependencyError, match=r"cannot load libfoo.so.3"):
        viz.check_offscreen()


def test_missing_vulkan_names_packages(monkeypatch, tmp_path):
    with pytest.raises(viz.VizDependencyError, match="libvulkan1"):
        viz._vulkan_devices(str(tmp_path / "libnovulkan.so.1"))
    monkeypatch.setenv("VK_ICD_FILENAMES", str(tmp_path / "no_icd.json"))
    monkeypatch.setenv("VK_DRIVER_FILES", str(tmp_path / "no_icd.json"))
    with pytest.raises(viz.VizDependencyError, match="mesa-vulkan-drivers"):
        viz._vulkan_devices()


def test_vulkan_device_found():
    assert viz._vulkan_devices() >= 1


def test_cli_without_open3d_one_line_exit_2(setup, tmp_path):
    code = (
        "import sys; sys.modules['open3d'] = None\n"
        "from meshrec.app.cli import main\n"
        f"sys.exit(main(['show', {str(setup.files / 'touch.csv')!r}, "
        f"'--screenshot', {str(tmp_path / 'x.png')!r}]))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1
    assert "open3d is not installed" in lines[0]
    assert "pip install" in lines[0]
    assert not (tmp_path / "x.png").exists()


def test_cli_rejects_bad_size(setup, capsys):
    code = main(["show", str(setup.files / "touch.csv"), "--size", "wide", "--screenshot", "x.png"])
    assert code == 2
    assert "WIDTHxHEIGHT" in capsys.readouterr().err


def test_truth_json_file_round_trip(setup):
    data = json.loads((setup.files / "truth.json").read_text(encoding="utf-8"))
    curves, contact = viz._load_truth(setup.files / "truth.json", setup.sim.touch, "ellipsoid")
    assert np.allclose(contact, data["contact"])
    assert len(curves) == len(setup.sim.touch.curves)

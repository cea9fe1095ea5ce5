"""trimesh imported on first use (meshrec._lazy): a Ctrl-C during its import is held and
raised once the import is done; a warm library load does not import it."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import types

import pytest

from meshrec import _lazy


def test_returns_the_module_already_imported():
    import trimesh

    assert _lazy.trimesh_module() is trimesh


@pytest.fixture
def default_sigint():
    """Python's own SIGINT handler for the test (a process started in the background or
    under nohup inherits SIGINT ignored, and then the import is left alone), restored
    after."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


def test_ctrl_c_during_the_import_is_raised_after_it(monkeypatch, default_sigint):
    fake = types.ModuleType("trimesh")
    done = []

    def slow_import(name):
        assert name == "trimesh"
        os.kill(os.getpid(), signal.SIGINT)  # swallowed here, as trimesh's imports do
        done.append(name)
        return fake

    monkeypatch.delitem(sys.modules, "trimesh")
    monkeypatch.setattr(_lazy.importlib, "import_module", slow_import)
    with pytest.raises(KeyboardInterrupt):
        _lazy.trimesh_module()
    assert done == ["trimesh"]  # the import ran to its end first
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_without_ctrl_c_the_import_is_returned(monkeypatch, default_sigint):
    fake = types.ModuleType("trimesh")
    monkeypatch.delitem(sys.modules, "trimesh")
    monkeypatch.setattr(_lazy.importlib, "import_module", lambda name: fake)
    assert _lazy.trimesh_module() is fake
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_an_ignored_sigint_is_left_alone(monkeypatch):
    # started in the background (SIGINT ignored): no handler is installed, none restored
    before = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        fake = types.ModuleType("trimesh")
        monkeypatch.delitem(sys.modules, "trimesh")
        monkeypatch.setattr(_lazy.importlib, "import_module", lambda name: fake)
        assert _lazy.trimesh_module() is fake
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, before)


def test_a_warm_recognition_imports_no_trimesh(tmp_path):
    cache, touch = str(tmp_path / "cache"), str(tmp_path / "touch.json")
    cold = (
        "import sys, meshrec\n"
        "lib = meshrec.ModelLibrary.from_folder(meshrec.bundled_models_dir('surfaces'), "
        f"cache_dir={cache!r})\n"
        f"meshrec.simulate_touch(lib['ellipsoid'], rng=3).touch.to_file({touch!r})\n"
        "assert 'trimesh' in sys.modules\n"  # the cold build and the simulation need it
    )
    subprocess.run([sys.executable, "-c", cold], check=True, timeout=300)
    warm = (
        "import sys, meshrec\n"
        "lib = meshrec.ModelLibrary.from_folder(meshrec.bundled_models_dir('surfaces'), "
        f"cache_dir={cache!r})\n"
        f"rec = meshrec.recognize(meshrec.TouchData.from_file({touch!r}), lib)\n"
        "print(rec.best.model, 'trimesh' in sys.modules)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", warm], check=True, timeout=300, capture_output=True, text=True
    )
    assert out.stdout.strip() == "ellipsoid False"

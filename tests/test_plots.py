"""meshrec.figures.plots and ``meshrec plot``: the paper's Figures 2, 3 and 6 as PNG files.

The phi profile is checked against a brute-force twin (its fine sampling of the same
error), the pictures for their size and for not being blank.
"""

import sys
from pathlib import Path

import numpy as np
import pytest
from matplotlib import image as mpimg

from meshrec.app.cli import main
from meshrec.figures import plots, viz
from meshrec.registration.register import register


def _png(path: Path) -> np.ndarray:
    return np.round(mpimg.imread(str(path))[..., :3] * 255.0).astype(np.int64)


def _not_blank(img: np.ndarray) -> None:
    assert img.std() > 10
    assert np.mean(np.all(img >= 250, axis=2)) < 0.98
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 20


@pytest.fixture(scope="module")
def setup(touched_ellipsoid):
    return touched_ellipsoid


@pytest.fixture(scope="module")
def traced(setup):
    return register(setup.sim.touch, setup.library["ellipsoid"], trace=True)


@pytest.fixture(scope="module")
def profile(setup, traced):
    return plots.phi_profile(traced, setup.library["ellipsoid"])


# ------------------------------------------------------------------ Figure 2: phi
def test_phi_profile_minimum_is_the_fine_samplings(profile):
    # Brute-force twin: the chosen phi is at least as good as the best of 720 angles,
    # and lies within two of their steps of it (modulo 2 pi).
    k = int(np.argmin(profile.errors))
    # (the brackets are refined to a tolerance: within 0.1% of the sampled minimum)
    assert profile.error <= profile.errors[k] * (1 + 1e-3) + 1e-9
    step = 2.0 * np.pi / len(profile.phis)
    gap = abs((profile.phi - profile.phis[k] + np.pi) % (2.0 * np.pi) - np.pi)
    assert gap <= 2.0 * step
    assert profile.minima[0, 0] == pytest.approx(profile.phi)
    assert len(profile.brackets) == len(profile.refined) >= 1
    assert profile.refined.any()


def test_phi_profile_default_candidate_has_the_least_sampled_error(setup, traced, profile):
    model = setup.library["ellipsoid"]
    others = [plots.phi_profile(traced, model, candidate=i, samples=36) for i in (0, 1)]
    for other in others:
        assert profile.grid_errors.min() <= other.grid_errors.min() + 1e-12


def test_phi_profile_of_an_unsearched_candidate_matches_its_fine_sampling(setup, traced):
    # A candidate the registration did not search gets its brackets refined by the same
    # stage: its minimum is within two fine steps of the best of 720 angles.
    searched = set(traced.trace.screening.candidates[: len(traced.trace.phis)].tolist())
    other = next(i for i in range(traced.candidates) if i not in searched)
    prof = plots.phi_profile(traced, setup.library["ellipsoid"], candidate=other)
    k = int(np.argmin(prof.errors))
    assert prof.error <= prof.errors[k] * (1 + 1e-3) + 1e-9
    gap = abs((prof.phi - prof.phis[k] + np.pi) % (2.0 * np.pi) - np.pi)
    assert gap <= 2.0 * (2.0 * np.pi / len(prof.phis))
    assert np.array_equal(prof.point, traced.candidate_points[other])


def test_phi_figure_writes_a_png_of_the_requested_size(profile, tmp_path):
    out = plots.phi_figure(profile, tmp_path / "sub" / "phi.png", size=(600, 300))
    assert out == tmp_path / "sub" / "phi.png"
    img = _png(out)
    assert img.shape == (300, 600, 3)
    _not_blank(img)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"samples": 10}, "samples must be an integer >= 36, got 10"),
        ({"samples": True}, "samples must be an integer"),
        ({"candidate": -1}, "candidate must be an index 0.."),
        ({"candidate": 10**6}, "candidate must be an index 0.."),
        ({"candidate": 1.5}, "candidate must be an index"),
    ],
)
def test_phi_profile_rejects_bad_arguments(setup, traced, kwargs, match):
    with pytest.raises(ValueError, match=match):
        plots.phi_profile(traced, setup.library["ellipsoid"], **kwargs)


def test_phi_profile_rejects_a_model_without_candidates_and_a_registration_without_trace(
    setup, traced
):
    box = setup.library["box"]
    with pytest.raises(ValueError, match="model 'box' has no candidate for this touch"):
        plots.phi_profile(register(setup.sim.touch, box, trace=True), box)
    with pytest.raises(ValueError, match="registration must be a Registration, got list"):
        plots.phi_profile([], setup.library["ellipsoid"])
    with pytest.raises(ValueError, match="registration must carry a trace"):
        plots.phi_profile(setup.rec.best, setup.library["ellipsoid"])
    with pytest.raises(ValueError, match="model must be 'ellipsoid', the model registered"):
        plots.phi_profile(traced, box)


def test_phi_figure_rejects_bad_arguments(profile, tmp_path):
    with pytest.raises(ValueError, match="profile must be a PhiProfile, got dict"):
        plots.phi_figure({}, tmp_path / "a.png")
    with pytest.raises(ValueError, match=r"\.png"):
        plots.phi_figure(profile, tmp_path / "a.jpg")
    with pytest.raises(ValueError, match="size must be"):
        plots.phi_figure(profile, tmp_path / "a.png", size=(10, 10))


# --------------------------------------------------------------- Figure 3: search
def test_search_figure_writes_a_png(setup, tmp_path):
    reg = setup.rec.best
    assert len(reg.search_paths) >= 1
    assert len(reg.candidate_points) == reg.candidates
    out = plots.search_figure(reg, tmp_path / "search.png", truth=setup.sim, size=(800, 400))
    img = _png(out)
    assert img.shape == (400, 800, 3)
    _not_blank(img)
    # the truth file gives the same picture as the SimulatedTouch
    again = plots.search_figure(
        reg, tmp_path / "again.png", truth=setup.files / "truth.json", size=(800, 400)
    )
    assert np.array_equal(_png(again), img)


def test_search_figure_rejects_bad_arguments(setup, tmp_path):
    with pytest.raises(ValueError, match="registration must be a Registration, got str"):
        plots.search_figure("reg", tmp_path / "a.png")
    rejected = next(r for r in setup.rec.ranking if r.rejected)
    with pytest.raises(ValueError, match="registration must not be rejected, got 'box'"):
        plots.search_figure(rejected, tmp_path / "a.png")
    with pytest.raises(ValueError, match=r"\.png"):
        plots.search_figure(setup.rec.best, tmp_path / "a.jpg")
    with pytest.raises(ValueError, match="cannot be read"):
        plots.search_figure(setup.rec.best, tmp_path / "a.png", truth=tmp_path / "none.json")


# ------------------------------------------------------- Figure 6: contacts
def test_contacts_figure_writes_one_panel_per_surface(setup, tmp_path):
    p, q = setup.sim.contact, setup.rec.best.contact
    groups = {"ellipsoid": [(p, q), (p, None)], "elsewhere": [(p, q)]}
    out = plots.contacts_figure(
        groups,
        tmp_path / "f6.png",
        meshes={"ellipsoid": setup.library["ellipsoid"]},
        size=(700, 350),
    )
    img = _png(out)
    assert img.shape == (350, 700, 3)
    _not_blank(img)


def test_contacts_figure_rejects_bad_arguments(setup, tmp_path):
    p = setup.sim.contact
    with pytest.raises(ValueError, match="columns must be a positive integer, got 0"):
        plots.contacts_figure({"a": [(p, p)]}, tmp_path / "a.png", columns=0)
    with pytest.raises(ValueError, match="meshes must be a mapping"):
        plots.contacts_figure({"a": [(p, p)]}, tmp_path / "a.png", meshes=[1])
    with pytest.raises(ValueError, match=r"\.png"):
        plots.contacts_figure({"a": [(p, p)]}, tmp_path / "a.jpg")


# ------------------------------------------------------------ dependencies, CLI
def test_missing_matplotlib_names_the_package(monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib.figure", None)
    with pytest.raises(viz.VizDependencyError, match="pip install 'meshrec\\[viz\\]'"):
        plots.check_matplotlib()


@pytest.mark.slow
def test_cli_plot_phi_and_search(setup, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("MESHREC_CACHE_DIR", str(setup.cache))
    touch = str(setup.files / "touch.csv")
    models = ["--models", str(setup.folder)]
    code = main(["plot", "phi", touch, *models, "-o", str(tmp_path / "phi.png")])
    assert code == 0
    assert "wrote" in capsys.readouterr().out
    _not_blank(_png(tmp_path / "phi.png"))
    truth = str(setup.files / "truth.json")
    code = main(["plot", "search", touch, *models, "--truth", truth, "-o", str(tmp_path / "s.png")])
    assert code == 0
    _not_blank(_png(tmp_path / "s.png"))
    bad = ["--candidate", "99999", "-o", str(tmp_path / "x.png")]
    code = main(["plot", "phi", touch, *models, *bad])
    assert code == 2
    err = capsys.readouterr().err
    assert err.startswith("meshrec: error: candidate must be an index")
    assert err.count("\n") == 1


def test_truth_contact_must_be_three_numbers(setup, tmp_path):
    for bad in ({"x": 1}, [1.0, 2.0], "abc"):
        truth = {**setup.sim.truth_dict(), "contact": bad}
        with pytest.raises(ValueError, match=r"truth\['contact'\] must be 3 finite numbers"):
            plots.search_figure(setup.rec.best, tmp_path / "a.png", truth=truth)
        with pytest.raises(ValueError, match=r"truth\['contact'\] must be 3 finite numbers"):
            viz.render(setup.rec, truth=truth, size=(32, 24))
    assert not (tmp_path / "a.png").exists()


def test_pictures_are_written_whole_or_not_at_all(tmp_path):
    from meshrec.figures._pixels import check_size, write_png_atomic

    with pytest.raises(ValueError, match="size must be"):
        check_size((float("inf"), 10), 16, 64)

    def fail(tmp):
        Path(tmp).write_bytes(b"\x89PNG half")
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError, match="No space left"):
        write_png_atomic(tmp_path / "pic.png", fail)
    assert list(tmp_path.iterdir()) == []
    out = write_png_atomic(tmp_path / "pic.png", lambda tmp: Path(tmp).write_bytes(b"png"))
    assert out.read_bytes() == b"png"
    assert [p.name for p in tmp_path.iterdir()] == ["pic.png"]


def test_cli_refuses_a_non_png_output_before_any_work(setup, tmp_path, capsys):
    touch = str(setup.files / "touch.csv")
    missing = str(tmp_path / "no_models")  # never reached: the output is checked first
    code = main(["plot", "search", touch, "--models", missing, "-o", str(tmp_path / "s.jpg")])
    assert code == 2
    assert capsys.readouterr().err == f"meshrec: error: {tmp_path / 's.jpg'} must end in .png\n"

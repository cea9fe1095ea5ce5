"""The phi grid by bounds against its brute-force twin, the whole grid.

Known answers: :func:`meshrec.registration.brackets.grid_errors` on every sample (the
brute-force twin); the ranking, pruning and screening starts recomputed from it by the
rules of stage 2; :func:`meshrec.registration.phi.search_phi` on its rows.
"""

import numpy as np
import pytest

from meshrec import bench, defaults
from meshrec.registration.bounded import bounded_grid_errors, exact_samples
from meshrec.registration.brackets import grid_errors, phi_brackets, phi_error, refine_phis
from meshrec.registration.lookup import lookup_candidates
from meshrec.registration.phi import search_phi
from meshrec.registration.register import touch_geometry
from meshrec.registration.sampling import even_subsample


def _cases(surfaces):
    """(model, candidates, subsample points) for seeded touches, right and wrong models."""
    out = []
    for seed, (shape, other) in enumerate(
        [("ellipsoid", "monkey_saddle"), ("crossed_trough", "elliptic_paraboloid")]
    ):
        touch = bench.paper_touch(surfaces[shape], seed).touch
        g = touch_geometry(touch)
        for name in (shape, other):
            cands = lookup_candidates(touch, surfaces[name], g)
            if len(cands):
                sub = even_subsample(len(cands.points), defaults.PHI_POINTS)
                local = [cands.local_points[k][sub] for k in cands.side]
                out.append((surfaces[name], cands, local))
    return out


@pytest.fixture(scope="module")
def cases(surfaces):
    return _cases(surfaces)


def test_exact_samples_are_the_grids_bits_and_the_others_bounds(cases):
    saved = 0
    for model, cands, local in cases:
        full = grid_errors(model, cands.origins, local, defaults.PHI_STEPS)
        b = bounded_grid_errors(model, cands.origins, local, defaults.PHI_STEPS)
        assert np.array_equal(b.errors[b.exact], full[b.exact])
        assert np.all(b.errors[~b.exact] <= full[~b.exact])
        # Every sample a later stage reads is exact: kept candidates' samples within the
        # refine ratio of their best.
        best = full.min(axis=1)
        kept = best <= defaults.SEARCH_PRUNE_RATIO * best.min()
        need = kept[:, None] & (full <= defaults.PHI_REFINE_RATIO * best[:, None])
        assert b.exact[need].all()
        assert b.settled[kept].all()
        assert np.array_equal(b.errors.min(axis=1)[kept], best[kept])
        saved += full.size * len(local[0]) - b.evaluated
    assert saved > 0


def test_ranked_settles_the_best_candidates(cases):
    for model, cands, local in cases:
        full = grid_errors(model, cands.origins, local, defaults.PHI_STEPS)
        best = full.min(axis=1)
        order = np.argsort(best, kind="stable")
        order = order[best[order] <= defaults.SEARCH_PRUNE_RATIO * best[order[0]]]
        b = bounded_grid_errors(
            model, cands.origins, local, defaults.PHI_STEPS, ranked=3, refine_ratio=1.0
        )
        assert b.settled[order[:3]].all()
        assert np.array_equal(b.errors.min(axis=1)[order[:3]], best[order[:3]])
        assert np.array_equal(b.errors[b.exact], full[b.exact])


def test_phi_brackets_and_refine_phis_read_what_the_whole_grid_gives(cases):
    for model, cands, local in cases:
        full = grid_errors(model, cands.origins, local, defaults.PHI_STEPS)
        best = full.min(axis=1)
        order = np.argsort(best, kind="stable")
        order = order[best[order] <= defaults.SEARCH_PRUNE_RATIO * best[order[0]]]
        brackets = phi_brackets(model, cands, distances="exact")
        limit = defaults.SCREEN_CANDIDATES
        assert np.array_equal(brackets.order[:limit], order[:limit])
        for i in order[:limit]:
            assert np.argmin(brackets.errors[i]) == np.argmin(full[i])
        chosen = order[:4]
        lean = refine_phis(model, cands, brackets, chosen, complete=False)
        whole = refine_phis(model, cands, brackets, chosen)
        for i, got, shown in zip(chosen, lean, whole, strict=True):
            error = phi_error(model, cands.origins[i], local[i])
            want = search_phi(error, steps=defaults.PHI_STEPS, grid_errors=full[i])
            assert got.phi == want.phi
            assert got.error == want.error
            assert np.array_equal(got.minima, want.minima)
            # complete=True: the whole row exact (pictures), the same angles.
            assert np.array_equal(shown.grid_errors, full[i])
            assert shown.phi == want.phi


def test_refine_phis_completes_a_row_whose_best_is_only_bounded(cases):
    checked = 0
    for model, cands, local in cases:
        brackets = phi_brackets(model, cands, ranked=1, distances="exact")
        e, x = brackets.errors, brackets.exact
        # Candidates whose least sample is only a bound: refined as on the whole grid.
        loose = [
            i
            for i in range(len(cands))
            if e[i][~x[i]].min(initial=np.inf) < e[i][x[i]].min()
        ]
        if not loose:
            continue
        full = grid_errors(model, cands.origins, local, defaults.PHI_STEPS)
        for i in loose[:2]:
            got = refine_phis(model, cands, brackets, [i], complete=False)[0]
            error = phi_error(model, cands.origins[i], local[i])
            want = search_phi(error, steps=defaults.PHI_STEPS, grid_errors=full[i])
            assert got.phi == want.phi
            assert np.array_equal(got.minima, want.minima)
            checked += 1
    assert checked > 0


def test_exact_samples_match_the_grid(cases):
    model, cands, local = cases[0]
    full = grid_errors(model, cands.origins, local, defaults.PHI_STEPS)
    which = np.array([0, 5, 17])
    got = exact_samples(model, cands.origins[2], local[2], defaults.PHI_STEPS, which)
    assert np.array_equal(got, full[2, which])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"prune_ratio": 0.5}, r"prune_ratio must be >= 1, got 0.5"),
        ({"refine_ratio": float("nan")}, r"refine_ratio must be >= 1, got nan"),
        ({"ranked": 0}, r"ranked must be a positive integer or None, got 0"),
        ({"rounds": (6, 6)}, r"rounds must be increasing, got \(6, 6\)"),
        ({"rounds": (0, 6)}, r"rounds must be a sequence of positive integers, got \(0, 6\)"),
        ({"rounds": (2.5,)}, r"rounds must be a sequence of positive integers, got \(2.5,\)"),
        ({"rounds": None}, r"rounds must be a sequence of positive integers, got None"),
    ],
)
def test_bad_arguments_raise(cases, kwargs, message):
    model, cands, local = cases[0]
    with pytest.raises(ValueError, match=message):
        bounded_grid_errors(model, cands.origins, local, 12, **kwargs)


def test_bad_point_sets_raise(cases):
    model, cands, local = cases[0]
    with pytest.raises(ValueError, match="origins and local_points must be as many"):
        bounded_grid_errors(model, cands.origins[:1], local[:2], 12)
    with pytest.raises(ValueError, match="origins and local_points must be as many"):
        bounded_grid_errors(model, (), [], 12)
    with pytest.raises(ValueError, match=r"local_points must all be \(n, 3\), got \(1, 4, 2\)"):
        bounded_grid_errors(model, cands.origins[:1], [np.zeros((4, 2))], 12)

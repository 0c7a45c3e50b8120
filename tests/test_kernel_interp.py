"""The integrator kernel's tractive-effort lookup: the piece hunted from the previous call's is the
binary search's, and the value is ``np.interp``'s to the bit, from every starting guess."""
import numpy as np
import pytest

from planner.physics import kernel


def _table(xp, fp):
    tab = np.zeros((3, len(xp)))
    tab[0], tab[1] = xp, fp
    with np.errstate(divide="ignore", invalid="ignore"):  # a tied speed's slope is ±inf/NaN, as numpy's
        tab[2, :-1] = np.diff(tab[1]) / np.diff(tab[0])  # as planner.physics.run_curve builds it
    return tab


def _probes(xp):
    """Every knot, the floats either side of it, points between, outside, ±inf and NaN."""
    x = np.concatenate([xp, np.nextafter(xp, -np.inf), np.nextafter(xp, np.inf), (xp[:-1] + xp[1:]) / 2,
                        [xp[0] - 1.0, xp[-1] + 1.0, -np.inf, np.inf, np.nan]])
    return x


@pytest.mark.parametrize("xp", [np.arange(24) * (5 / 3.6),  # the sample's speeds (every 5 km/h) in m/s
                                np.array([0.0, 0.3, 0.31, 2.0, 7.5, 7.50000001, 40.0])])
def test_hunted_interp_is_np_interp_from_every_guess(xp):
    fp = 3e5 / (1.0 + xp) + np.sin(xp) * 1e3
    tab = _table(xp, fp)
    for x in _probes(xp):
        want = np.interp(x, xp, fp)
        for j in range(len(xp) - 1):
            got, j_next = kernel._interp(x, tab, j)
            assert np.array_equal(got, want, equal_nan=True) and np.signbit(got) == np.signbit(want), (x, j)
            if xp[0] <= x < xp[-1]:
                assert j_next == kernel._bracket(x, tab), (x, j)


def test_hunt_finds_the_binary_search_piece_when_speeds_tie():
    # strictly increasing km/h can round to equal m/s: the one piece with xp[j] <= x < xp[j+1] is
    # still unique, and the hunt must find the binary search's from any guess
    xp = np.array([0.0, 1.0, 2.0, 2.0, 2.0, 3.0, 4.0])
    tab = _table(xp, np.arange(7.0))
    for x in [0.0, 0.5, 1.0, np.nextafter(2.0, 0.0), 2.0, 2.5, 3.0, np.nextafter(4.0, 0.0)]:
        for j in range(len(xp) - 1):
            assert kernel._interp(x, tab, j)[1] == kernel._bracket(x, tab), (x, j)

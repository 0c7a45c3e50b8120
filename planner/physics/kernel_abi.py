"""The integrator kernel's interface, importable without numba: array rows, checks, and which code runs.

:mod:`planner.physics.kernel` is the kernel's source (numba). A process runs
either its build from install time (:mod:`planner.io.compiled`, ``planner
kernels build``) or, where there is none for these exact sources, the source
compiled just in time on first use (about 5 s of CPU per process). :func:`load`
picks once per process; numba itself is imported only in the second case.
:func:`check_layout` guards the built functions, which do not check their
arguments.
"""
from __future__ import annotations

from types import ModuleType

import numpy as np

from planner.io import compiled

PHASE_POWER, PHASE_HOLD, PHASE_COAST, PHASE_BRAKE, PHASE_STOP = 0, 1, 2, 3, 4
SAWTOOTH_MIN_FRACTION = 0.5
"""A sawtooth vehicle coasts down to ``max(target − band, 0.5 × target)``: at low
targets a full band would coast to a crawl (or a standstill on a rise)."""

# rows of trk (per node): running distance, on-board maximum², 2b × distance to the
# segment end, stopping curve², track acceleration, on-board maximum of the interval k → k+1,
# 1.0 where a_track ≥ a_max (the cap may bind below coasting there)
T_S, T_VN2, T_AHEAD, T_STOP2, T_AG, T_VINT, T_STEEP = range(7)
# rows of par (per run): Davis A, B, C and traction factor, all / M_e; ratio², cruise cap², ratio,
# cruise cap, shedding deceleration
P_RAM, P_RBM, P_RCM, P_TFI, P_R2, P_CAP2, P_RATIO, P_CAPV, P_SHED = range(9)
# rows of st (per run): time, speed, speed², traction work / M_e, ceiling² at the node, speed² entering
# the last step, the first step after which its time was not finite (+inf: none)
S_T, S_V, S_W, S_WORK, S_C0, S_WLAST, S_BAD = range(7)
# then the sweep's scratch rows (kernel._sweep: what one stage of a run's step hands the next):
# tractive-effort piece, ceiling² ahead, band edge, coasting, a₀, coasting a₀, ṽ₁, coasting a₁, slope,
# unbounded end, crossing, fraction before it, end, above the ceiling
(X_J, X_C1, X_LB, X_CO, X_A0, X_CS0, X_VP, X_CS1, X_SLOPE, X_WEND, X_CROSS, X_FRAC, X_W1,
 X_OVER) = range(7, 21)
S_ROWS = 21
LANES = 8
"""At most this many runs are stepped together by the kernel (``kernel._sweep``): enough independent
chains for the processor to overlap (4, 8 and 16 measured alike), in even groups (9 runs: 5 + 4)."""
L_PHASE, L_COAST = range(2)
# flags: any run may be above its ceiling; last node the stall check passed; stall window (from, to)
# and the first run found stalled there
F_MAYBE_OVER, F_K_OK, F_STALL_FROM, F_STALL_TO, F_STALL_RUN = range(5)
# rows of rec (record=True): time, speed, acceleration, ratio, cruise cap at each node
R_T, R_V, R_A, R_RATIO, R_CAP = range(5)
# rows of inc (planner.physics.reuse): the time and the traction work / M_e of the step arriving at a node, as
# added to the run's sums
I_DT, I_DWORK = range(2)
NO_INC, NO_SLOT = np.empty((2, 1, 1)), np.empty(0, np.int64)
"""``inc`` and ``slot`` of an ``advance`` that keeps no increments (an empty ``slot``: the kernel writes nothing)."""
NO_REC, NO_REC_P = np.empty((5, 1, 1)), np.empty((1, 1), np.int8)
"""``rec`` and ``rec_p`` of an ``advance`` that records no curves (``record`` False: the kernel writes nothing)."""

SOURCES = ("planner.physics.kernel", __name__, "planner.io.compiled")
"""What a build of the kernel is made of (their digest names the built module)."""

_LAYOUT = {"trk": (np.float64, 2), "seg": (np.int64, 1), "bounds": (np.int64, 1), "par": (np.float64, 2),
           "st": (np.float64, 2), "lane": (np.int8, 2), "e": (np.float64, 2), "cst": (np.float64, 1),
           "tab": (np.float64, 2), "flags": (np.int64, 1), "rec": (np.float64, 3), "rec_p": (np.int8, 2),
           "inc": (np.float64, 3), "slot": (np.int64, 1), "lead": (np.int64, 1), "sums": (np.float64, 1)}


def check_layout(**arrays: np.ndarray) -> None:
    """Raise if an array for the kernel is not of its dtype, rank and C order (the kernel's signatures)."""
    for name, a in arrays.items():
        dtype, ndim = _LAYOUT[name]
        if not (type(a) is np.ndarray and a.dtype == dtype and a.ndim == ndim and a.flags.c_contiguous):
            raise TypeError(f"kernel array {name}: expected C-contiguous {np.dtype(dtype)} of rank {ndim}, got "
                            f"{getattr(a, 'dtype', type(a))} of rank {getattr(a, 'ndim', '?')}")


_loaded: ModuleType | None = None


def load() -> ModuleType:
    """The kernel's entry points (``advance``, ``set_targets``, ``follow``): its build for these sources, else
    the source."""
    global _loaded
    if _loaded is None:
        built = compiled.load("integrator", SOURCES)
        if built is None:
            from planner.physics import kernel as built
        _loaded = built
    return _loaded


def backend() -> str:
    """``"aot"``: this process runs the build from install; ``"jit"``: numba compiles the source here."""
    return "jit" if load().__name__ == "planner.physics.kernel" else "aot"

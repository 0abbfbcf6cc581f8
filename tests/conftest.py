"""Shared fixtures: the shipped machines (planner/problems/cranes/*.toml), each once per
session.

``crane`` runs a test on every machine; ``cranab850``, ``umea_lab``, ``s100f`` and ``cat215b``
name one. ``random_configs`` draws joint configurations inside a machine's limits.
"""
import numpy as np
import pytest
from hypothesis import settings

from planner import Crane
from planner.problems import crane_ids

settings.register_profile("ci", max_examples=60, deadline=None, derandomize=True,
                          print_blob=True)
settings.load_profile("ci")

MACHINES = crane_ids()


@pytest.fixture(scope="session", params=MACHINES)
def crane(request):
    """Every shipped machine in turn."""
    return Crane.from_id(request.param)


@pytest.fixture(scope="session")
def cranab850():
    return Crane.from_id("cranab850")


@pytest.fixture(scope="session")
def umea_lab():
    return Crane.from_id("umea-lab")


@pytest.fixture(scope="session")
def s100f():
    return Crane.from_id("s100f")


@pytest.fixture(scope="session")
def cat215b():
    return Crane.from_id("cat215b")


def random_configs(crane, n, seed=0, margin=0.02):
    """n random joint configurations strictly inside the limits."""
    rng = np.random.default_rng(seed)
    L = crane.limit_arrays()
    lo = L["q_min"] + margin * (L["q_max"] - L["q_min"])
    hi = L["q_max"] - margin * (L["q_max"] - L["q_min"])
    return lo + rng.random((n, crane.n)) * (hi - lo)


def random_tip_moves(crane, n, seed):
    """``n`` (start, goal) tip pairs from random joint configurations inside 10 % margins."""
    rng = np.random.default_rng(seed)
    L = crane.limit_arrays()
    lo = L["q_min"] + 0.1 * (L["q_max"] - L["q_min"])
    hi = L["q_max"] - 0.1 * (L["q_max"] - L["q_min"])
    qs = lo + rng.random((2 * n, crane.n)) * (hi - lo)
    return [tuple(tuple(float(x) for x in np.round(crane.tip(q), 3)) for q in (qs[k], qs[n + k]))
            for k in range(n)]


def check_adjoint(shooting, x0, us, W, m: int, rng, directions: int = 3):
    """Assert that ``shooting``'s adjoint gradient of J = Σ W·x (the states from ``x0`` under
    the per-step commands ``us``) matches central differences of the same forward runs along
    smooth random directions of the first ``m`` steps' commands."""
    from scipy.signal import butter, filtfilt

    def J(uu):
        return float(np.sum(W * shooting.run(x0, uu).x))

    g = shooting.gradient(shooting.run(x0, us), us, W)
    b, a = butter(2, 0.02)
    for _ in range(directions):
        d = np.zeros_like(us)
        d[:m] = filtfilt(b, a, rng.normal(size=(m, us.shape[1])), axis=0) * 0.05
        eps = 1e-4
        fd = (J(us + eps * d) - J(us - eps * d)) / (2 * eps)
        assert np.sum(g * d) == pytest.approx(fd, rel=2e-3, abs=1e-9 * abs(fd) + 1e-12)


def step_commands(shooting, u, extra_steps):
    """(R, K, us): 50 Hz commands ``u`` (M, n) held on the twin's step grid (R steps per
    command) and padded with ``extra_steps`` closed steps to whole chunks of ``shooting``
    (K steps in all)."""
    R = int(round(0.02 / shooting.h))
    K = shooting.steps(len(u) * R + extra_steps)
    us = np.zeros((K, u.shape[1]))
    us[:len(u) * R] = np.repeat(u, R, axis=0)
    return R, K, us

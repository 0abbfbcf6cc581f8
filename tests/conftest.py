import numpy as np
import pytest
from hypothesis import settings

from planner import Crane

settings.register_profile("ci", max_examples=60, deadline=None, derandomize=True,
                          print_blob=True)
settings.load_profile("ci")

MACHINES = ["cranab850", "umea-lab", "s100f", "cat215b"]


@pytest.fixture(scope="session", params=MACHINES)
def crane(request):
    return Crane.from_id(request.param)


def random_configs(crane, n, seed=0, margin=0.02):
    """n random joint configurations strictly inside the limits."""
    rng = np.random.default_rng(seed)
    L = crane.limit_arrays()
    lo = L["q_min"] + margin * (L["q_max"] - L["q_min"])
    hi = L["q_max"] - margin * (L["q_max"] - L["q_min"])
    return lo + rng.random((n, crane.n)) * (hi - lo)

"""The public API of ``planner`` (its ``__all__``): every name resolves, and what :func:`plan`
raises can be caught without reaching into :mod:`planner.methods`.

The oracle for "unsupported" is the method's own declaration (``objectives``): a registered
method that plans only ``time`` must refuse an ``energy`` request with the exported exception,
before it plans anything.
"""
import pytest

import planner
from planner import PlanRequest, PlanResult, UnsupportedRequest, plan
from planner.methods import Planner, register, unregister

START, GOAL = (6.0, -1.0, 0.0), (3.0, 2.5, 1.5)


class TimeOnly(Planner):
    """Plans only minimum time; remembers whether it was ever asked to plan."""
    name = "test:time-only"
    objectives = ("time",)
    paths = ("free",)
    called = False

    def plan(self, crane, request):
        TimeOnly.called = True
        return PlanResult("infeasible", "a test method plans nothing")


@pytest.fixture
def time_only():
    TimeOnly.called = False
    register(TimeOnly())
    yield TimeOnly.name
    unregister(TimeOnly.name)


def test_every_public_name_resolves():
    for name in planner.__all__:
        assert getattr(planner, name) is not None, name
    assert {"UnsupportedRequest", "PlanRequest", "PlanResult", "plan"} <= set(planner.__all__)


def test_the_exported_exception_is_the_one_the_methods_raise():
    from planner.methods.base import UnsupportedRequest as inner
    assert UnsupportedRequest is inner and issubclass(UnsupportedRequest, ValueError)


def test_plan_with_an_objective_the_method_does_not_plan_raises_it(s100f, time_only):
    request = PlanRequest(START, GOAL, objective="energy", path="free")
    with pytest.raises(UnsupportedRequest, match="energy") as info:
        plan(s100f, request, method=time_only)
    assert time_only in str(info.value) and "time" in str(info.value)
    assert TimeOnly.called is False                     # refused before any planning
    # the same method plans the objective it declares (a result status, not an exception)
    res = plan(s100f, PlanRequest(START, GOAL, objective="time", path="free"), method=time_only)
    assert TimeOnly.called and res.status == "infeasible"


def test_a_built_in_method_refuses_an_objective_it_lacks(s100f):
    # Ruckig is time-optimal only (planner.methods.ruckig declares objectives = ("time",))
    with pytest.raises(UnsupportedRequest, match="energy"):
        plan(s100f, PlanRequest(START, GOAL, objective="energy", path="free"), method="ruckig")


def test_an_objective_no_method_knows_is_refused_when_the_request_is_made():
    with pytest.raises(UnsupportedRequest, match="objective 'speed': allowed time, energy"):
        PlanRequest(START, GOAL, objective="speed")

"""The benchmark's method list: its named variants, then every other registered method.

Variants (:data:`VARIANTS`, the bench's own names, each with a runner per suite kind): ``law:NAME``
the seeds' local laws (:mod:`planner.methods.laws`, :mod:`planner.methods.laws_energy`) along
the suite's path at :attr:`Settings.law_speed`, or on a cycle's clock (``follow_command``);
``ruckig`` jerk-limited rest-to-rest joint move; ``dp:time`` Bellman minimum time along the
path; ``dp:energy`` / ``dp:energy-pinned`` the energy DP along a cycle's sections at the
cycle's tip speed, telescope chained (first section free / pinned to the laws' start);
``topp:dp`` TOPP-RA (velocity, acceleration, pump) on the DP's joint path; ``topp:law`` the
same on every law's joint path, the fastest feasible one (the laws made feasible under the
spec's limits); ``nlp:time-free`` / ``nlp:time-path`` minimum-time MoveNLP, free path / on the
suite's line or curve; ``nlp:time-free-kin`` the same free-path NLP with the seed-000 limit set
(acceleration and jerk ×:attr:`Settings.kin_factor`, judged like the laws on position, velocity
and pump flow); ``nlp:time-free-acc`` the same without a jerk limit (TOPP-RA's limit set, to
compare with ``topp:law``); ``nlp:energy-free`` least pump energy within
:attr:`Settings.energy_budget` × the minimum time (``energy_optimal``); ``nlp:energy-path`` per
cycle section, the least pump energy on the line within the section's time, telescope chained;
``nlp:kin-line`` the velocity-only line NLP (``kinematic_line_nlp``, seed 000's model).

Every registered method (:func:`planner.methods.registry.available`) that no variant covers
(``law:q_optimal`` among the built-ins, and any method registered by a plug-in or a test) joins
the list after the variants and runs through
:func:`planner.bench.runners.generic_runner` where its declared paths, objectives and obstacle
handling fit the suite (:func:`planner.bench.runners.fit`), else it is "n/a" with the reason.

Which variants a suite runs is data, in the suite's task file (``[bench] methods``, see
:mod:`planner.bench.suites`); what is logic stays here: a variant runs only on the suite kinds
it has a runner for, ``law:max_lift`` needs the machine's ``[laws] max_lift`` table, and
``--quick`` skips ``nlp:energy-path``.
"""
from __future__ import annotations

from dataclasses import dataclass

from planner.bench import cycle_runners as cr
from planner.bench import runners as rn
from planner.bench.context import Settings
from planner.methods.registry import available

KINDS = ("p2p", "path", "cycle")   # suite kinds: point to point, on a curve, timed cycles
SEED_LAWS = ("least_norm", "max_velocity", "max_lift", "jla", "p_optimal")


@dataclass(frozen=True)
class Variant:
    """A named bench method: the registered method it ``covers`` and its runner per suite
    kind (a kind missing: the variant does not run on such suites)."""
    covers: str
    runners: dict


def _law(name):
    r = rn.law_runner(name)
    return Variant(f"law:{name}", dict(p2p=r, path=r, cycle=r))


VARIANTS = {
    **{f"law:{n}": _law(n) for n in SEED_LAWS},
    "ruckig": Variant("ruckig", dict(p2p=rn.ruckig)),
    "dp:time": Variant("dp", dict(p2p=rn.dp_time, path=rn.dp_time)),
    "dp:energy": Variant("dp", dict(cycle=cr.dp_energy_cycle)),
    "dp:energy-pinned": Variant("dp", dict(cycle=cr.dp_energy_cycle_pinned)),
    "topp:dp": Variant("topp", dict(p2p=rn.topp_dp, path=rn.topp_dp, cycle=cr.topp_dp_cycle)),
    "topp:law": Variant("topp", dict(p2p=rn.topp_law, path=rn.topp_law)),
    "nlp:time-free": Variant("nlp", dict(p2p=rn.nlp_time_free)),
    "nlp:time-free-kin": Variant("nlp", dict(p2p=rn.nlp_time_free_kin)),
    "nlp:time-free-acc": Variant("nlp", dict(p2p=rn.nlp_time_free_acc)),
    "nlp:time-path": Variant("nlp", dict(p2p=rn.nlp_time_path, path=rn.nlp_time_path)),
    "nlp:energy-free": Variant("nlp", dict(p2p=rn.nlp_energy_free)),
    "nlp:energy-path": Variant("nlp", dict(cycle=cr.nlp_energy_cycle)),
    "nlp:kin-line": Variant("nlp", dict(p2p=rn.nlp_kin_line)),
}
METHODS = tuple(VARIANTS)   # the variants' names, in the report's order
LAW_VARIANTS = tuple(m for m in METHODS if m.startswith("law:"))


def method_names() -> list[str]:
    """The bench's method list: the variants, then every registered method no variant covers
    (sorted), read from the registry now (a method registered later joins later runs)."""
    covered = {v.covers for v in VARIANTS.values()}
    return list(METHODS) + [n for n in available() if n not in covered]


def applicability(suite, spec_file: str, listed, not_applicable: dict, default_reason: str,
                  crane_id: str, max_lift: bool, settings: Settings) -> dict:
    """Per method of :func:`method_names`: its runner on ``suite`` or the "n/a" reason.
    ``listed``: the variants the suite file names (``[bench] methods``), ``not_applicable``:
    the file's reasons by method, ``default_reason`` for the other variants; ``max_lift``:
    whether the machine ``crane_id`` has a ``[laws] max_lift`` table."""
    out = {}
    for m in listed:
        if m not in VARIANTS:
            raise ValueError(f"{spec_file}: [bench] methods: unknown variant {m!r}; allowed: "
                             f"{', '.join(METHODS)}")
        if suite.kind not in VARIANTS[m].runners:
            raise ValueError(f"{spec_file}: [bench] methods: {m!r} has no runner for "
                             f"{suite.kind} suites (it runs on "
                             f"{', '.join(VARIANTS[m].runners)} suites)")
    for m in method_names():
        if m in VARIANTS:
            out[m] = (VARIANTS[m].runners[suite.kind] if m in listed
                      else not_applicable.get(m, default_reason))
            continue
        path = rn.fit(m, suite)
        out[m] = rn.generic_runner(m, path) if path in ("free", "line") else path
    if callable(out.get("law:max_lift")) and not max_lift:
        out["law:max_lift"] = (f"{crane_id} has no [laws] max_lift table: seed 000's "
                               "maximum-lifting-capacity circle is defined for the Cranab 850 only")
    if settings.quick and callable(out.get("nlp:energy-path")):
        out["nlp:energy-path"] = ("skipped in a quick run (≈ 1 min per cycle: an energy NLP "
                                  "per section)")
    return out


__all__ = ["METHODS", "VARIANTS", "LAW_VARIANTS", "SEED_LAWS", "KINDS", "Variant",
           "method_names", "applicability"]

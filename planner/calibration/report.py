"""The discrepancy report: markdown, the JSON result and the figures of a
:class:`planner.calibration.discrepancy.DiscrepancyResult`."""
from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

from planner.io import atomic_write_text, write_json

if TYPE_CHECKING:
    from planner.model import Crane
    from planner.calibration.discrepancy import DiscrepancyResult

__all__ = ["write_report"]


def _fmt(v, unit=""):
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    return f"{v:.4g}{unit}"


def write_report(res: DiscrepancyResult, out_dir, *, crane: Crane, measured: str = "",
                 closed: dict | None = None) -> list:
    """Markdown report, JSON result and figures into ``out_dir`` (created); every file is
    written atomically. Returns the paths written."""
    from planner.plots import (discrepancy_overlay_figure,  # matplotlib: only when drawn
                               discrepancy_ranking_figure, discrepancy_residual_figure)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    figs = {"residuals.png": discrepancy_residual_figure, "overlay.png":
            discrepancy_overlay_figure, "ranking.png": discrepancy_ranking_figure}
    for name, f in figs.items():
        f(res, out / name)
    js = res.to_json()
    if closed is not None:
        js["closed_loop"] = closed
    write_json(out / "result.json", js)
    w = res.where
    L = [f"# Model discrepancy: {crane.spec.id}", "",
         f"Measured: `{measured}` — {len(res.series['t'])} samples, "
         f"{res.series['t'][-1] - res.series['t'][0]:.1f} s; held-out: alternate 1 s blocks.",
         "", "**Question**: does the nominal model explain the measurement, and if not, which "
         "effect is missing?", "", f"**Verdict**: {res.verdict}.", "",
         f"**Answer**: {res.message}.", ""]
    L += [f"Note: {x}" for x in res.notes] + ([""] if res.notes else [])
    if res.candidates:
        L += ["| candidate | joint | score | predictions differ most |", "| --- | --- | ---: | --- |"]
        L += [f"| {c['effect']} | {c['joint'] or ''} | {c['score']:.1f} | "
              + ", ".join(f"{d['joint']} {d['condition']} ({d['channel']})"
                          for d in c.get("differs_most", [])[:2]) + " |"
              for c in res.candidates] + [""]
    if res.signature:
        L += ["| residual signature | channel | RMS / noise | share of the excess |",
              "| --- | --- | ---: | ---: |"]
        L += [f"| {g['kind']} | {g['channel']} | {g['rms_over_noise']:.2f} | "
              f"{100 * g['share']:.0f} % |" for g in res.signature[:6]] + [""]
    if res.effect:
        L += ["| parameter | estimate | standard error |", "| --- | ---: | ---: |"]
        for k, v in res.parameters.items():
            if k != "joint":
                L.append(f"| {res.effect}.{k} | {_fmt(v)} | {_fmt(res.uncertainty.get(k))} |")
        if res.second:
            for k, v in res.second["parameters"].items():
                L.append(f"| {res.second['effect']}.{k} (second) | {_fmt(v)} | "
                         f"{_fmt(res.second['uncertainty'].get(k))} |")
        L += ["", f"Identifiable (scaled Jacobian well conditioned): "
                  f"{'yes' if res.identifiable else 'NO — treat the estimate with care'}.", ""]
    L += ["## Where the disagreement lives (nominal model)", "",
          "| channel | residual RMS / noise |", "| --- | ---: |"]
    L += [f"| {c['channel']} | {c['rms_over_noise']:.2f} |" for c in w["channels"][:8]]
    L += ["", f"{w['n_windows']} windows of 2 s stand out (RMS > 2 σ in some channel)"
          + (": " + ", ".join(f"{x['t0']:.0f}–{x['t1']:.0f} s ({x['channel']})"
                              for x in w["windows"][:6]) if w["windows"] else "") + ".", ""]
    worst = w["channels"][0]["channel"] if w["channels"] else None
    if worst:
        j = worst.split("_")[1]
        cond = w["conditions"].get(j, {})
        L += [f"Mean square residual of joint {j} (in σ², noise = 1) by operating condition: "
              + ", ".join(f"{k} {v:.2f}" for k, v in cond.items() if v is not None) + ".", ""]
    L += ["## Candidate effects (held-out score = ΔJ − k·ln n; named above "
          f"{res.series['threshold']:g})", "",
          "| rank | model | parameters | score | cond |", "| ---: | --- | --- | ---: | ---: |"]
    for r in res.ranking[:10]:
        ps = "; ".join(", ".join(f"{k}={v:.4g}" for k, v in e.items()
                                 if k not in ("name", "joint")) for e in r["effects"])
        L.append(f"| {r['rank']} | {r['model']} | {ps} | {r['score']:.1f} | {r['cond']:.3g} |")
    L += ["", "## The gap, before and after (held-out blocks)", "",
          "| channel | noise σ | RMS before | RMS after | VAF before | VAF after | "
          "above-noise removed |", "| --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for c in res.rms_before:
        g = res.gap_reduction_channels.get(c)
        L.append(f"| {c} | {_fmt(res.noise[c])} | {_fmt(res.rms_before[c])} | "
                 f"{_fmt(res.rms_after[c])} | {res.vaf_before[c]:.1f} % | "
                 f"{res.vaf_after[c]:.1f} % | {'–' if g is None else f'{100 * g:.0f} %'} |")
    L += ["", f"Overall share of the above-noise residual removed: "
              f"**{100 * res.gap_reduction:.0f} %**.", ""]
    if closed is not None:
        b, a = closed["before"], closed["after"]
        L += ["## Closing the loop", "",
              ("Predicted on the calibrated model" if closed["predicted"] else
               "On the plant") + ": open-loop tip tracking error of the commanded trajectory "
              f"with the nominal feed-forward {1e3 * b['rms_m']:.1f} mm RMS "
              f"({1e3 * b['max_m']:.1f} mm max), with the feed-forward re-planned on the "
              f"calibrated model {1e3 * a['rms_m']:.1f} mm RMS ({1e3 * a['max_m']:.1f} mm max)"
              + (f"; the re-planned move takes {a['duration_s']:.2f} s instead of "
                 f"{b['duration_s']:.2f} s (the pump cannot follow the original timing)"
                 if a["duration_s"] > b["duration_s"] * 1.001 else "") + ".", ""]
    L += ["![residuals](residuals.png)", "", "![overlay](overlay.png)", "",
          "![ranking](ranking.png)", "", f"Runtime {res.runtime_s:.1f} s."]
    atomic_write_text(out / "report.md", "\n".join(L) + "\n")
    return [out / "report.md", out / "result.json"] + [out / n for n in figs]

"""The fidelity result as a text table: each real session, the pooled real and the scene."""

from __future__ import annotations

from typing import Any

import numpy as np

from ext_sense_sim.fidelity import food, taps
from ext_sense_sim.fidelity.check import POOLED, SIMULATED
from ext_sense_sim.fidelity.compare import AUC_MARGIN

CELL = 21


def number(x: float | None) -> str:
    """A short rendering: ``10.5k``, ``618``, ``42.5``, ``0.26``; ``-`` for none."""
    if x is None or not np.isfinite(x):
        return "-"
    a = abs(x)
    if a >= 1000:
        return f"{x / 1000:.1f}k"
    if a >= 100:
        return f"{x:.0f}"
    if a >= 10:
        return f"{x:.1f}"
    return f"{x:.2f}"


def _cell(s: dict[str, float]) -> str:
    return f"{number(s['median'])} [{number(s['p25'])}-{number(s['p75'])}]"


def short_names(names: list[str]) -> dict[str, str]:
    """Session names without the prefix they share (``nuskin_rod_taps_2021-03-24`` -> date)."""
    if len(names) < 2:
        return {n: n for n in names}
    shared = ""
    for chars in zip(*names, strict=False):
        if len(set(chars)) > 1:
            break
        shared += chars[0]
    cut = shared.rfind("_") + 1
    return {n: n[cut:] or n for n in names}


def _measure(kind: str, value: float) -> str:
    if not np.isfinite(value):
        return "-"
    return f"x{value:.2f}" if kind == "ratio" else f"{value:+.2f}"


def format_table(result: dict[str, Any]) -> str:
    """The CLI's table of a :func:`~ext_sense_sim.fidelity.check.run_fidelity` result."""
    groups = result["groups"]
    real = result["sessions"]
    short = short_names(real)
    cols = [*real, POOLED, SIMULATED]
    heads = [short.get(c, c) for c in cols]
    tap = result["kind"] == "tap"
    stats = taps.STATS if tap else food.STATS
    lines = [_title(result)]
    for name in real:
        g = groups[name]
        missed = f", {len(g['missed'])} missed" if tap else ""
        lines.append(
            f"  {short[name]}: {g['windows']} of {g['captures']} captures{missed}  ({g['path']})"
        )
    sim = groups[SIMULATED]
    extra = ""
    if tap:
        extra = (
            f", {len(sim['missed'])} missed, {len(sim['cut_short'])} cut short; found onset - "
            f"true onset median {number(result['onset_error_ms_median'])} ms"
        )
    lines.append(
        f"  simulated: {sim['windows']} of {result['trials']} trials, seed {result['seed']}{extra}"
    )
    lines.append("")
    width = max(len(v) for v in stats.values()) + 2
    target = {t["stat"]: t for t in result.get("targets", [])}
    lines.append(
        "median [p25-p75]".ljust(width)
        + "".join(h[: CELL - 1].ljust(CELL) for h in heads)
        + ("sim vs pooled  target" if tap else "sim / pooled")
    )
    for key, label in stats.items():
        row = label.ljust(width) + "".join(
            _cell(groups[c]["summary"][key]).ljust(CELL) for c in cols
        )
        s, r = groups[SIMULATED]["summary"][key]["median"], groups[POOLED]["summary"][key]["median"]
        if key in target:
            t = target[key]
            verdict = "pass" if t["pass"] else "FAIL"
            row += f"{_measure(t['kind'], t['value']):15s}{t['allowed']:11s}{verdict}"
        elif tap and key not in taps.RATIO_STATS:
            row += _measure("diff", s - r)
        elif r:
            row += f"x{s / r:.2f}"
        lines.append(row)
    lines.append("")
    lines.extend(_auc_lines(result, short, width))
    if tap:
        lines.append("")
        lines.extend(_per_session_targets(result, short, width))
    else:
        lines.append("")
        lines.append("events/s per class in both (median, trials): real | simulated")
        for label, c in result["per_class"].items():
            lines.append(
                f"  {label:14s} {number(c['real_median']):>7s} ({c['real_n']:2d}) | "
                f"{number(c['sim_median']):>7s} ({c['sim_n']:2d})"
            )
    if result.get("pass") is not None:
        lines.append("")
        lines.append(f"fidelity targets: {'all pass' if result['pass'] else 'FAIL'}")
    return "\n".join(lines)


def _title(result: dict[str, Any]) -> str:
    n = len(result["sessions"])
    what = (
        f"{result['rod_cm']} cm rod taps"
        if result["kind"] == "tap"
        else (f"food trials, {result['span_s']:g} s after the motion start")
    )
    return f"{result['scene']} against {n} real session{'s' * (n > 1)} ({what})"


AUC_BLOCKS = {
    "target": "targeted statistics",
    "table": "issue's 5 statistics",
    "all": "all statistics",
    "trial": "per-trial statistics",
}


def _auc_lines(result: dict[str, Any], short: dict[str, str], width: int) -> list[str]:
    lines = []
    for key, auc in result["auc"].items():
        what = AUC_BLOCKS[key]
        row = f"AUC sim vs real, {what}".ljust(width)
        row += "".join(number(auc["sim_vs_session"].get(n)).ljust(CELL) for n in result["sessions"])
        lines.append(row + number(auc["sim_vs_pooled"]).ljust(CELL))
        if auc["real_vs_real"]:
            pairs = ", ".join(
                f"{' vs '.join(short[x] for x in pair.split(' | '))} {number(v)}"
                for pair, v in auc["real_vs_real"].items()
            )
            lines.append(f"AUC real vs real, {what}".ljust(width) + pairs)
    if result["kind"] == "tap":
        auc = result["auc"]["target"]
        if auc["pass"] is None:
            lines.append("AUC target".ljust(width) + "needs two real sessions (no yardstick)")
        else:
            verdict = "pass" if auc["pass"] else "FAIL"
            lines.append(
                "AUC target".ljust(width)
                + f"targeted statistics: sim vs pooled {number(auc['sim_vs_pooled'])} <= "
                f"real vs real {number(auc['yardstick'])} + {AUC_MARGIN:g}: {verdict}"
            )
    return lines


def _per_session_targets(result: dict[str, Any], short: dict[str, str], width: int) -> list[str]:
    targets = result["targets"]
    head = "targets per real session".ljust(width)
    head += "".join(f"{t['stat']} {t['allowed']}".ljust(CELL) for t in targets)
    lines = [head]
    for name in result["sessions"]:
        row = f"  sim vs {short[name]}".ljust(width)
        for t in targets:
            p = t["per_session"][name]
            row += f"{_measure(t['kind'], p['value'])} {'pass' if p['pass'] else 'FAIL'}".ljust(
                CELL
            )
        lines.append(row)
    return lines

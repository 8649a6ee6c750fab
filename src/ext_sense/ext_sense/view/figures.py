"""``ext-sense plot``'s figures: a session overview and one figure per contact (matplotlib).

matplotlib is imported inside the functions (``Agg``), so importing this module is cheap.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from ext_sense.view.sessions import Contact, PlotSession
from ext_sense_runtime.stamps import MS, S

MAX_BINS = 1500


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def rate_map(session: PlotSession, max_bins: int = MAX_BINS) -> tuple[np.ndarray, np.ndarray, int]:
    """Events per taxel per second on the session's timeline.

    Returns:
        ``(rates (n_channels, n_bins) events/s, bin edges ns from the first event, t0 ns)``.
    """
    ev = session.events
    n_ch = 80 if session.sensor == "nuskin" else max(2, int(ev.taxel.max(initial=1)))
    if not ev.size:
        return np.zeros((n_ch, 1)), np.array([0, S]), 0
    t0 = int(ev.t_ns.min())
    span = max(int(ev.t_ns.max()) - t0, MS)
    bin_ns = max(MS, -(-span // max_bins))
    n_bins = span // bin_ns + 1
    idx = ((ev.t_ns - t0) // bin_ns).astype(np.int64)
    ch = ev.taxel.astype(np.int64) - 1
    ok = (ch >= 0) & (ch < n_ch)
    counts = np.zeros((n_ch, n_bins))
    np.add.at(counts, (ch[ok], idx[ok]), 1.0)
    return counts / (bin_ns / S), np.arange(n_bins + 1) * bin_ns, t0


def overview_figure(session: PlotSession, out: Path, dpi: int = 110) -> Path:
    """Event rate per taxel over time with the contacts marked, and the rate per finger."""
    plt = _pyplot()
    rates, edges, t0 = rate_map(session)
    seconds = edges / S
    fig, (ax, ax2) = plt.subplots(
        2,
        1,
        figsize=(11, 5.2),
        sharex=True,
        gridspec_kw={"height_ratios": [3, 1]},
        layout="constrained",
    )
    img = ax.imshow(
        np.log10(1 + rates),
        aspect="auto",
        origin="lower",
        interpolation="nearest",
        extent=(seconds[0], seconds[-1], 0.5, rates.shape[0] + 0.5),
        cmap="viridis",
    )
    fig.colorbar(img, ax=[ax, ax2], pad=0.01, label="log10(1 + events/s) per taxel")
    nuskin = session.sensor == "nuskin"
    if nuskin:
        ax.axhline(40.5, color="white", lw=0.6)
    ax.set_ylabel("taxel (1-40 left, 41-80 right)" if nuskin else "BioTac sensor")
    for c in session.contacts:
        ax.axvline((c.onset_ns - t0) / S, color="red", lw=0.7, alpha=0.8)
        ax2.axvline((c.onset_ns - t0) / S, color="red", lw=0.7, alpha=0.5)
    centres = seconds[:-1]
    if nuskin:
        ax2.plot(centres, rates[:40].sum(axis=0), lw=0.7, label="left finger")
        ax2.plot(centres, rates[40:].sum(axis=0), lw=0.7, label="right finger")
        ax2.legend(loc="upper right", fontsize=7)
    else:
        ax2.plot(centres, rates.sum(axis=0), lw=0.7, label="frames")
    ax2.set_ylabel("events/s")
    ax2.set_xlabel("time from the first event, s")
    ax.set_title(
        f"{session.name}: {session.task or 'unknown task'}, {session.sensor}, "
        f"{session.events.size} events, {len(session.contacts)} contacts (red)"
    )
    fig.savefig(out, dpi=dpi)
    plt.close(fig)
    return out


def _describe(c: Contact) -> str:
    est, truth = c.estimate, c.truth
    parts = []
    if est is not None:
        if math.isfinite(est.tap_position_m):
            parts.append(
                f"estimate {est.tap_position_m * 100:.1f} ± {est.tap_position_std_m * 100:.1f} cm"
            )
        elif est.class_label:
            parts.append(f"estimate {est.class_label}")
        if math.isfinite(est.stability_probability):
            parts.append(f"P(stable) {est.stability_probability:.2f}")
        parts.append(f"latency {est.compute_latency_ns / 1e6:.1f} ms")
    if truth is not None:
        if math.isfinite(truth.tap_position_m):
            parts.append(f"true {truth.tap_position_m * 100:.1f} cm")
            if est is not None and math.isfinite(est.tap_position_m):
                parts.append(f"error {abs(est.tap_position_m - truth.tap_position_m) * 100:.1f} cm")
        elif truth.class_label:
            parts.append(f"true {truth.class_label}")
    return " | ".join(parts) or "no estimate or truth in the source"


def contact_figure(session: PlotSession, c: Contact, out: Path, dpi: int = 110) -> Path:
    """The events around one contact (onset red, window shaded), beside its estimate and truth."""
    plt = _pyplot()
    ev = session.events
    lo = min(c.start_ns, c.onset_ns) - 50 * MS
    hi = max(c.end_ns, c.onset_ns) + 50 * MS
    sel = (ev.t_ns >= lo) & (ev.t_ns <= hi)
    t_ms = (ev.t_ns[sel] - c.onset_ns) / MS
    taxel = ev.taxel[sel].astype(int)
    est, truth = c.estimate, c.truth
    has_panel = est is not None or (truth is not None and math.isfinite(truth.tap_position_m))
    fig = plt.figure(figsize=(10, 4.2))
    ax = fig.add_axes((0.07, 0.13, 0.6 if has_panel else 0.9, 0.74))
    colours = np.where(taxel <= 40, "tab:blue", "tab:orange")
    ax.scatter(t_ms, taxel, s=1.5, c=colours, marker="|", linewidths=0.6)
    ax.axvspan(
        (c.start_ns - c.onset_ns) / MS, (c.end_ns - c.onset_ns) / MS, color="0.85", zorder=-1
    )
    ax.axvline(0, color="red", lw=1)
    ax.set_xlim((lo - c.onset_ns) / MS, (hi - c.onset_ns) / MS)
    ax.set_ylim(0.5, 80.5 if session.sensor == "nuskin" else taxel.max(initial=2) + 0.5)
    ax.set_xlabel("time from onset, ms (grey: the window)")
    ax.set_ylabel("taxel (blue left, orange right)")
    ax.set_title(f"{session.name}, {c.name}: {len(t_ms)} events", fontsize=10)
    fig.text(0.07, 0.94, _describe(c), fontsize=9)
    if has_panel:
        side = fig.add_axes((0.73, 0.13, 0.24, 0.74))
        _estimate_panel(side, est, truth)
    fig.savefig(out, dpi=dpi)
    plt.close(fig)
    return out


def _estimate_panel(ax: Any, est: Any, truth: Any) -> None:
    if est is not None and est.class_probabilities:
        names = list(est.class_names) or [str(i) for i in range(len(est.class_probabilities))]
        colours = ["tab:orange" if i == est.class_index else "tab:blue" for i in range(len(names))]
        bars = ax.barh(names, est.class_probabilities, color=colours)
        if truth is not None and truth.class_label in names:
            bars[names.index(truth.class_label)].set_edgecolor("green")
            bars[names.index(truth.class_label)].set_linewidth(2.5)
        ax.set_xlim(0, 1)
        ax.set_xlabel("probability (green frame: true class)")
        return
    rod = truth.rod_length_m if truth is not None and math.isfinite(truth.rod_length_m) else 0.3
    ax.plot([0, rod * 100], [0, 0], color="0.5", lw=8, solid_capstyle="butt")
    if est is not None and math.isfinite(est.tap_position_m):
        x, s = est.tap_position_m * 100, est.tap_position_std_m * 100
        ax.errorbar(
            [x],
            [0.25],
            xerr=[s if math.isfinite(s) else 0],
            fmt="v",
            color="tab:orange",
            label="estimate ± std",
        )
    if truth is not None and math.isfinite(truth.tap_position_m):
        ax.plot([truth.tap_position_m * 100], [-0.25], "^", color="green", label="truth")
    ax.set_ylim(-1, 1)
    ax.set_yticks([])
    ax.set_xlabel("position along the rod from the grip, cm")
    ax.legend(loc="upper center", fontsize=7)


def plot_session(
    session: PlotSession, out_dir: Path, max_contacts: int = 20, dpi: int = 110
) -> list[Path]:
    """Write ``overview.png`` and ``contact_NNN.png`` for the first ``max_contacts`` contacts."""
    out_dir.mkdir(parents=True, exist_ok=True)
    written = [overview_figure(session, out_dir / "overview.png", dpi)]
    for k, c in enumerate(session.contacts[:max_contacts]):
        written.append(contact_figure(session, c, out_dir / f"contact_{k + 1:03d}.png", dpi))
    return written

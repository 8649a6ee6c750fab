"""The report's per-dataset sections: fingers and taxels, decision latency (no ROS)."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np

from ext_sense_perception.data.window_set import WindowSet
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.reporting.plots import plot
from ext_sense_perception.reporting.runner import LINEAR_MODEL, Runner, Study
from ext_sense_perception.reporting.scores import coverage, ece, fmt, score, spread
from ext_sense_runtime.stamps import MS


def gru_row(ws: WindowSet, gru: bool | None = None) -> bool:
    """Whether the table gets the GRU row: NUSkin taps unless ``gru`` is False.

    BioTac is left out: its raw PAC gives 660-step sequences, about 10x the training time.
    """
    return gru is not False and ws.task == "tap_localization" and ws.sensor == "nuskin"


def dataset_name(ws: WindowSet, path: Path | str) -> str:
    """File-name stem of a data set's plots: task, sensor and the data's folder name."""
    return dataset_name_of(ws.task, ws.sensor, path)


def dataset_name_of(task: str, sensor: str, path: Path | str) -> str:
    """:func:`dataset_name` from the task, sensor and path a section heading shows.

    The last part is a ``dataset.npz``'s folder, another file's folder and stem, or a directory's
    name; a path with a suffix is a file, so data no longer on disk gives the same name.
    """
    src = Path(str(path))
    if not src.suffix:
        where = src.name
    elif src.stem == "dataset":
        where = src.parent.name
    else:
        where = f"{src.parent.name}_{src.stem}"
    return f"{task}_{sensor}_{where}"


def taxel_section(
    ws: WindowSet, run: Runner, name: str, feat0: str, model0: str, n_top: int
) -> list[str]:
    """Both fingers against one finger against one taxel, default and linear model side by side.

    The single taxel is a hyper-parameter among the ``n_top`` most active (no label used), picked
    by each split's grid search on its training part; its rows say ``channels`` ``taxel:N`` (the
    modal pick), ``taxel_per_split`` and ``taxel_candidates``.
    """
    g = ws.geometry
    cols = [model0] + ([LINEAR_MODEL] if model0 != LINEAR_MODEL else [])
    activity = np.abs(ws.X).sum(axis=(0, 2))
    top = np.sort(np.argsort(activity, kind="stable")[::-1][:n_top])  # 0-based channel rows
    sub = ws._replace(
        X=np.ascontiguousarray(ws.X[:, top, :]), geometry=g._replace(n_channels=len(top))
    )
    taxel_grid = {"features__channels": [f"taxel:{i + 1}" for i in range(len(top))]}
    ids = ", ".join(str(int(t) + 1) for t in top)
    header = " | ".join(f"{feat0} + {m}" + (" (default)" if m == model0 else "") for m in cols)
    lines = [
        "### Two fingers, one finger, one taxel",
        "",
        f"K = {run.k_text} splits; the linear model weighs each standardised feature on its "
        "own, the RBF kernel weighs all alike (off-strip taxels dilute it).",
        "",
        f"| taxels | {header} |",
        "|---|" + "---|" * len(cols),
    ]
    for sel, label in [
        (None, f"both fingers ({g.n_channels})"),
        ("left", f"one finger (1-{g.n_channels // 2})"),
        ("right", f"one finger ({g.n_channels // 2 + 1}-{g.n_channels})"),
    ]:
        cells = []
        for m in cols:
            try:
                res = run(ws, name, feat0, m, channels=sel)
            except PerceptionError as err:
                cells.append(f"failed: {err}")
                continue
            cells.append(fmt(res))
            run.row(res, Study.TAXELS, channels=sel or "all")
        lines.append(f"| {label} | {' | '.join(cells)} |")
    cells, picks = [], []
    for m in cols:
        try:
            res = run(sub, name, feat0, m, extra_grid=taxel_grid)
        except PerceptionError as err:
            cells.append(f"failed: {err}")
            continue
        cells.append(fmt(res))
        chosen = [
            int(top[int(p["features__channels"].split(":")[1]) - 1]) + 1 for p in res.best_params
        ]
        picks.append(f"{m}: {', '.join(str(c) for c in chosen)}")
        modal = Counter(chosen).most_common(1)  # empty while the section is only planned
        run.row(
            res,
            Study.TAXELS,
            channels=f"taxel:{modal[0][0]}" if modal else "taxel",
            taxel_per_split=chosen,
            taxel_candidates=[int(t) + 1 for t in top],
        )
    lines += [
        f"| one taxel, chosen per split on the training part among the {len(top)} most active "
        f"({ids}) | {' | '.join(cells)} |",
        "",
        f"Taxel chosen in each split: {'; '.join(picks)}.",
        "",
    ]
    return lines


def latency_section(
    ws: WindowSet, run: Runner, name: str, out: Path, feat0: str, model0: str
) -> list[str]:
    """Score against the post-contact window (decision latency), with anytime calibration.

    The paper's linear model is scored beside the default on the same splits, as in the taxel
    section: the two weigh the later part of a window differently.
    """
    lower = ws.is_regression
    g = ws.geometry
    full_post = g.n_samples * g.period_ns - g.pre_ns
    posts = [p for p in ws.task_profile.study_post_ns() if p <= full_post]
    linear = [LINEAR_MODEL] if model0 != LINEAR_MODEL else []
    lines = [
        f"### Decision latency ({feat0} + {model0}); anytime calibration",
        "",
        "| post-contact window ms | score | "
        + ("95% PI coverage | PI half-width cm |" if lower else "ECE | Brier |")
        + "".join(f" {m} score |" for m in linear),
        "|---|---|---|---|" + "---|" * len(linear),
    ]
    dx, dy, derr = [], [], []
    for p in posts:
        cut = ws.crop(p)  # one copy of the shorter windows for both models
        res = run(cut, name, feat0, model0)
        run.row(res, Study.DECISION_LATENCY)
        if lower:
            cal = f"{coverage(res):.2f} | {1.959964 * float(np.mean(res.y_std)) * 100:.2f}"
        else:
            calibration_error, brier = ece(res)
            cal = f"{calibration_error:.3f} | {brier:.3f}"
        beside = []
        for m in linear:
            try:
                other = run(cut, name, feat0, m)
            except PerceptionError as err:
                beside.append(f"failed: {err}")
                continue
            beside.append(fmt(other))
            run.row(other, Study.DECISION_LATENCY)
        lines.append(f"| {p / MS:g} | {fmt(res)} | {cal} |" + "".join(f" {c} |" for c in beside))
        dx.append(p / MS)
        dy.append(score(res))
        derr.append(spread(res))
    png = out / f"{name}_vs_decision_latency.png"
    plot(
        png,
        dx,
        dy,
        "post-contact window = decision latency floor (ms)",
        "MAE (cm)" if lower else "accuracy",
        f"{ws.task} {ws.sensor}: score vs decision latency",
        pareto_lower=lower,
        yerr=derr,
    )
    lines += ["", f"![score vs decision latency]({png.name})", ""]
    return lines

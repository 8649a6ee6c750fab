"""The report's files: report.md and report.json written, a former report read back (no ROS).

The data-set and rod-length tables are rebuilt from the rows at every write, so a report
updated data set by data set (``--update``) stays consistent.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.reporting.runner import Study
from ext_sense_perception.reporting.scores import fmt_values
from ext_sense_perception.reporting.sections import dataset_name_of


class ReportParts(NamedTuple):
    """A report's data-set sections (by data-set name, in order) and its report.json rows."""

    sections: dict[str, list[str]]
    records: list[dict[str, Any]]


SIM_COMMIT = re.compile(r"[\w.+-]{4,64}")
SECTION_HEADING = re.compile(r"^## (\w+), (\w+) \(\d+ windows; `([^`]+)`")


def read_report(out: Path) -> ReportParts:
    """The data-set sections of ``out/report.md`` (told by their headings) and report.json's rows.

    PerceptionError: report.json is not a list of rows.
    """
    md, js = out / "report.md", out / "report.json"
    if not md.exists() and not js.exists():
        return ReportParts({}, [])
    try:
        records = json.loads(js.read_text())
        text = md.read_text()
    except (OSError, ValueError) as err:
        raise PerceptionError(f"Cannot read the former report in {str(out)!r}: {err}") from err
    if not isinstance(records, list) or not all(isinstance(r, dict) for r in records):
        raise PerceptionError(f"The former {str(js)!r} must be a list of rows (JSON objects).")
    sections: dict[str, list[str]] = {}
    current: list[str] | None = None
    for line in text.splitlines():
        if line.startswith("## "):
            hit = SECTION_HEADING.match(line)
            current = None
            if hit:
                current = sections.setdefault(dataset_name_of(*hit.groups()), [])
        elif line.startswith("(In progress:"):
            current = None
        if current is not None:
            current.append(line)
    return ReportParts(sections, records)


def provenance(path: Path, sim_commit: str | None) -> dict[str, Any]:
    """Where a data set's rows come from: ``simulator`` (a scene's npz) or ``recording``."""
    if Path(path).suffix == ".npz":
        with np.load(path, allow_pickle=False) as z:
            if "scene" in z.files:
                return {
                    "source": "simulator",
                    "scene": str(z["scene"]),
                    "seed": int(z["seed"]) if "seed" in z.files else None,
                    "sim_commit": sim_commit,
                }
    return {"source": "recording", "scene": None, "seed": None, "sim_commit": None}


def source_lines(prov: dict[str, Any]) -> list[str]:
    """The sentence under a data set's heading saying where its windows come from."""
    if prov["source"] != "simulator":
        return ["Recorded data (not simulated).", ""]
    scene, seed, commit = prov["scene"], prov["seed"], prov["sim_commit"] or "not given"
    return [f"Simulated: scene `{scene}`, seed {seed}, simulator commit {commit}.", ""]


def sources_table(records: list[dict[str, Any]]) -> list[str]:
    """One line per data set: where its rows come from and how many there are."""
    seen: dict[str, list[dict[str, Any]]] = {}
    for r in records:
        seen.setdefault(r["dataset"], []).append(r)
    lines = [
        "## Data sets",
        "",
        "Every row of report.json names its data set, its `study` (models, decision_latency, "
        "sampling_rate, taxels, rod_length) and its parameters (`post_ms`, `rate_hz`, "
        "`channels`, `rod_m`); a point shown by several studies is one evaluation listed under "
        "each (the same `point`).",
        "",
        "| data set | source | scene, seed | simulator commit | rows |",
        "|---|---|---|---|---|",
    ]
    for name, rows in seen.items():
        r = rows[0]
        scene = f"{r.get('scene')}, {r.get('seed')}" if r.get("scene") else ""
        lines.append(
            f"| {name} | {r.get('source', '?')} | {scene} | {r.get('sim_commit') or ''} "
            f"| {len(rows)} |"
        )
    return [*lines, ""]


def rod_table(records: list[dict[str, Any]]) -> list[str]:
    """The rod-length table from the rows of study ``rod_length`` (two rods or more)."""
    rods = [r for r in records if r.get("study") == Study.ROD_LENGTH.value and r.get("rod_m")]
    if len(rods) < 2:
        return []
    lines = [
        "## Rod length (tap localisation, default model)",
        "",
        "| rod m | sensor | MAE | MAE / length | simulator commit |",
        "|---|---|---|---|---|",
    ]
    for r in sorted(rods, key=lambda r: (r["sensor"], r["rod_m"])):
        mae = fmt_values(r["metric"], r["mean"], r["std"])
        lines.append(
            f"| {r['rod_m']:.2f} | {r['sensor']} | {mae} "
            f"| {r['mean'] / r['rod_m']:.3f} | {r.get('sim_commit') or ''} |"
        )
    return [*lines, ""]


def write_report(out: Path, parts: ReportParts, note: str | None = None) -> Path:
    """Write ``report.md`` and ``report.json`` (rows in section order); returns the first."""
    place = {name: i for i, name in enumerate(parts.sections)}
    records = sorted(parts.records, key=lambda r: place.get(r.get("dataset"), len(place)))
    lines = [
        "# ext_sense perception report",
        "",
        "Generated by `ext-sense report`. Scores are mean +- std over the K random 90/10 splits of "
        "the paper's protocol (MAE in cm for tap localisation, accuracy otherwise).",
        "",
        *sources_table(records),
    ]
    for section in parts.sections.values():
        lines += section
    lines += rod_table(records)
    if note:
        lines.append(note)
    md = out / "report.md"
    md.write_text("\n".join(lines) + "\n")
    (out / "report.json").write_text(json.dumps(records, indent=2, default=str) + "\n")
    return md

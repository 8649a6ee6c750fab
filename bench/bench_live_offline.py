"""Live against offline on the same trials: tap MAE, handover accuracy, release-rule fraction.

    python bench/bench_live_offline.py            # 30 taps + 10 grasps per condition (~7 min)
    python bench/bench_live_offline.py --quick    # 6 taps + 2 grasps, quiet and loaded (~3 min)
    python bench/bench_live_offline.py --json out.json --models DIR

Issue #16's target: live within 10% of offline on a quiet machine, 25% with both cores loaded.
Per condition (``quiet``, ``loaded``: a busy loop per core, ``+priority``: ``reader_priority:=50``,
``+one_process``: ``hot_path:=one_process``) it runs ``ext-sense run tap_localization`` and
``ext-sense run handover behaviours:=true`` (the Robotiq emulator served from here) on the
simulator beside ``ext-sense record``, then scores the same trials ``live`` (as published),
``bag`` (``ext-sense replay --offline``'s core on the recorded packets: what the live graph
loses) and ``plan`` (simulated again from the seed, cut with ideal reads as models are trained:
adds what the arrival clock does).

MAE and accuracy as the monitor's ``Scoreboard``; the release-rule fraction is the share of
stable grasps on which ``HandoverMachine``'s rule opens. Ratios below 1: live is worse. Each
run's line ends with the emulated sensor's late writes (the figures hold if it wrote on time).
"""

from __future__ import annotations

import argparse
import contextlib
import itertools
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from common import start_hog, stop_group, stop_hog

from ext_sense.topics import (
    SENSOR_PACKETS,
    TOPIC_ESTIMATE,
    TOPIC_GROUND_TRUTH,
    TOPIC_HANDOVER_OFFER,
)
from ext_sense_runtime.records import Estimate, GroundTruth

EXE = [sys.executable, "-m", "ext_sense.cli"]
SENSOR = "nuskin"
TARGETS = {"quiet": 0.10, "loaded": 0.25}
"""Largest |1 - live/offline| per load, the part of a condition before any ``+`` (issue #16)."""
MODIFIERS = ("priority", "one_process")
"""What may follow a load in a condition, each after a ``+``."""
PRIORITY = 50
GRASP_TRIALS = 4
TRIAL_PERIOD_NS = 1_000_000_000
"""``sim_device``'s trial spacing (``trial_period_s``), used to lay the planned trials out."""
RECORDER_START_TIMEOUT_S = 30.0
DECISION_TOPIC = "/handover/decision"
OBJECT_POSITION = 128
"""Where the emulated gripper's fingers stop on the offered object (as the scenario tests)."""


@dataclass(frozen=True)
class Task:
    """A graph and its task label."""

    graph: str
    task: str


TAP = Task("tap_localization", "tap_localization")
HANDOVER = Task("handover", "handover_stability")


@dataclass
class Score:
    """One way of scoring one run's trials."""

    scored: int = 0
    trials: int = 0
    mae_cm: float = math.nan
    accuracy: float = math.nan
    release_fraction: float = math.nan
    stable_grasps: int = 0
    released_grasps: int = 0
    unmatched: int = 0
    degraded: int = 0  # final estimates flagged degraded: not scored, as the monitor does


@dataclass
class RunResult:
    """A live run and its offline counterparts."""

    task: str
    condition: str
    load_before: str
    load_after: str
    wall_s: float
    seed: int
    trials_requested: int
    trial_numbers: list[int]
    live: Score
    bag: Score
    plan: Score
    monitor_summary: str = ""
    live_releases: int = -1
    packets: int = 0
    packet_seq_gaps: int = 0
    emulator: str = ""  # the emulated sensor's own count of late writes


# ------------------------------------------------------------------------------ environment
def loadavg() -> str:
    """/proc/loadavg as it reads (the machine is shared: every run says what it ran beside)."""
    return Path("/proc/loadavg").read_text().strip()


def ensure_models(out: Path) -> dict[str, Path]:
    """The two tasks' default models, trained into ``out`` unless current ones are there."""
    from ext_sense_perception.online.model_store import default_name
    from ext_sense_sim.default_models import create_models

    tasks = (TAP.task, HANDOVER.task)
    create_models(out, SENSOR, tasks, log=lambda line: print(line, file=sys.stderr))
    return {t: out / default_name(t, SENSOR) for t in tasks}


# ------------------------------------------------------------------------------ processes
@contextlib.contextmanager
def recording(bag: Path, topics: Sequence[str], env: dict[str, str], log: Path) -> Iterator[None]:
    """``ext-sense record`` of ``topics`` into ``bag`` while the block runs, up before it."""
    with log.open("wb") as out:
        proc = subprocess.Popen(
            [*EXE, "record", str(bag), "--topics", *topics],
            stdout=out,
            stderr=subprocess.STDOUT,
            env=env,
            start_new_session=True,
        )
    try:
        deadline = time.monotonic() + RECORDER_START_TIMEOUT_S
        while b"recording" not in log.read_bytes():
            if proc.poll() is not None or time.monotonic() > deadline:
                raise SystemExit(f"bench_live_offline: the recorder did not start: {log}")
            time.sleep(0.1)
        yield
        time.sleep(1.0)  # the last estimates and a flush
    finally:
        stop_group(proc)


@contextlib.contextmanager
def gripper_emulator() -> Iterator[str]:
    """The Robotiq 2F emulator on a pty, served from this process; yields the port."""
    from ext_sense_sim.devices.robotiq_emulator import GripperModel, PtyGripper, RobotiqEmulator

    with PtyGripper(
        RobotiqEmulator(GripperModel(activation_s=0.05, object_position=OBJECT_POSITION))
    ) as pty:
        yield pty.path


def run_graph(
    task: Task, args: dict[str, str], env: dict[str, str], log: Path, timeout_s: float
) -> str:
    """``ext-sense run`` until its estimate monitor ends it (or the timeout); the summary line."""
    argv = [*EXE, "run", task.graph, *(f"{k}:={v}" for k, v in args.items())]
    with log.open("wb") as out:
        proc = subprocess.Popen(
            argv, stdout=out, stderr=subprocess.STDOUT, env=env, start_new_session=True
        )
    try:
        proc.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        print(f"[live-offline] {task.graph}: still running after {timeout_s:.0f} s, stopped")
    finally:
        stop_group(proc)
    lines = [x for x in log.read_text(errors="replace").splitlines() if "summary:" in x]
    return lines[-1].split("summary:", 1)[1].strip() if lines else ""


def emulator_lateness(log: Path) -> str:
    """``sim_device``'s last count of late writes in a graph log ("" when it logged none)."""
    marker = "so far: "
    lines = [x for x in log.read_text(errors="replace").splitlines() if "[sim_device]" in x]
    last = next((x for x in reversed(lines) if marker in x), "")
    return last.split(marker, 1)[1].rstrip(")") if last else ""


# ------------------------------------------------------------------------------ scoring
def scoreboard_score(task: Task, truths: Sequence[GroundTruth], ests: Sequence[Estimate]) -> Score:
    """MAE or accuracy as the estimate monitor computes it (its ``Scoreboard``)."""
    from ext_sense.nodes.scoreboard import Scoreboard

    board = Scoreboard(task.task)
    for t in truths:
        board.add_truth(t)
    for e in sorted(ests, key=lambda e: e.onset_ns):
        board.add_estimate(e)
    board.close()
    out = Score(
        scored=board.scored,
        trials=len(truths),
        unmatched=board.unmatched_estimates,
        degraded=len(board.degraded),
    )
    if board.is_regression and board.errors_m:
        out.mae_cm = 100.0 * sum(board.errors_m) / len(board.errors_m)
    elif board.correct:
        out.accuracy = sum(board.correct) / len(board.correct)
    return out


def reaches_release(ests: Sequence[Estimate]) -> bool:
    """Whether the handover node's own release rule (``HandoverMachine``) opens on these."""
    from ext_sense_behaviours.handover import HandoverAction, HandoverMachine

    machine = HandoverMachine()
    machine.start(0)
    for i, est in enumerate(sorted(ests, key=lambda e: e.onset_ns)):
        decision = machine.on_estimate(est, i + 1)
        if HandoverAction[decision.action] == HandoverAction.OPEN_GRIPPER:
            return True
    return False


def release_fraction(
    score: Score,
    truths: Sequence[GroundTruth],
    ests: Sequence[Estimate],
    grasps: Sequence[Sequence[int]],
) -> None:
    """Fill ``score``'s release-rule figures from the final estimates in each stable grasp's
    span (half a trial before its first onset up to the next grasp's)."""
    label = {t.trial: t.class_label for t in truths}
    onset = {t.trial: t.onset_ns for t in truths}
    starts = [min(onset.get(k, 2**62) for k in g) - TRIAL_PERIOD_NS // 2 for g in grasps]
    starts.append(2**62)
    released = stable = 0
    for k, grasp in enumerate(grasps):
        if label.get(grasp[0]) != "stable":
            continue
        stable += 1
        its = [e for e in ests if starts[k] <= e.onset_ns < starts[k + 1]]
        released += reaches_release(its)
    score.stable_grasps, score.released_grasps = stable, released
    score.release_fraction = released / stable if stable else math.nan


def grasps_of(truths: Sequence[GroundTruth], offers: Sequence[int]) -> list[list[int]]:
    """Trial numbers of each grasp: the trials whose onset follows one offer, before the next."""
    edges = [*sorted(offers), 2**62]
    out: list[list[int]] = [[] for _ in offers]
    for t in sorted(truths, key=lambda t: t.onset_ns):
        for k in range(len(offers)):
            if edges[k] <= t.onset_ns < edges[k + 1]:
                out[k].append(t.trial)
    return [g for g in out if g]


# ------------------------------------------------------------------------------ the bag
def read_bag(bag: Path) -> dict[str, Any]:
    """Truths, live final and provisional estimates, offers, decisions and packet seq of a bag."""
    from ext_sense_bags import BagReader
    from ext_sense_runtime.records import estimate_of, truth_of
    from ext_sense_runtime.stamps import stamp_to_ns

    out: dict[str, Any] = {"truths": [], "estimates": [], "offers": [], "decisions": []}
    seqs: list[int] = []
    packets = SENSOR_PACKETS[SENSOR]
    with BagReader(bag) as reader:
        topics = (TOPIC_GROUND_TRUTH, TOPIC_ESTIMATE, TOPIC_HANDOVER_OFFER, DECISION_TOPIC, packets)
        wanted = [t for t in topics if t in reader.topics]
        for rec, msg in reader.messages(wanted):
            if rec.topic == TOPIC_GROUND_TRUTH:
                out["truths"].append(truth_of(msg))
            elif rec.topic == TOPIC_ESTIMATE:
                out["estimates"].append(estimate_of(msg))
            elif rec.topic == TOPIC_HANDOVER_OFFER:
                out["offers"].append(stamp_to_ns(msg.header.stamp))
            elif rec.topic == DECISION_TOPIC:
                out["decisions"].append(str(msg.data))
            else:
                seqs.append(int(msg.seq))
    seqs.sort()
    out["packets"] = len(seqs)
    out["seq_gaps"] = sum(max(0, b - a - 1) for a, b in itertools.pairwise(seqs))
    return out


def load(model_dir: Path) -> tuple[Any, Any]:
    """The model as the inference node loads it, and the windows its card asks for."""
    from ext_sense_perception.online.predictor import load_model
    from ext_sense_perception.online.window import WindowConfig

    model = load_model(model_dir, "onnx")
    return model, WindowConfig(model.card.profile, SENSOR)


def bag_estimates(bag: Path, model_dir: Path) -> list[Estimate]:
    """``ext-sense replay BAG --offline``'s estimates: the live bytes through the graph's core."""
    from ext_sense.offline_replay import offline_estimates

    model, config = load(model_dir)
    return [
        e
        for kind, e in offline_estimates(bag, config, model)
        if kind == "estimate" and not e.provisional
    ]


# ------------------------------------------------------------------------------ the plan
def planned(scene_name: str, seed: int, numbers: Sequence[int]) -> tuple[list, list[GroundTruth]]:
    """The writes ``(t_ns, bytes)`` of trials ``numbers`` as ``sim_device`` simulates them for
    ``seed``, laid 1 s apart, and their truths stamped as the device stamps them live."""
    from ext_sense_sim.scene import load_scene
    from ext_sense_sim.trial_plan import plan_trials

    scene = load_scene(scene_name)
    rod = scene.geometry.length_m if scene.geometry.kind == "rod" else math.nan
    wanted = sorted(set(numbers))
    slot = {k: i for i, k in enumerate(wanted)}
    writes: list[tuple[int, bytes]] = []
    truths: list[GroundTruth] = []
    for plan in plan_trials(scene, seed):
        if plan.trial > wanted[-1]:
            break
        if plan.trial not in slot:
            continue
        t0 = slot[plan.trial] * TRIAL_PERIOD_NS
        writes += [(t0 + int(t), b) for t, b in plan.chunks]
        first = next((t for t, _ in plan.chunks if t >= plan.onset_ns), None)
        if first is not None:
            truths.append(
                GroundTruth(
                    plan.trial,
                    t0 + int(first),
                    scene.task.label,
                    plan.tap_position_m,
                    plan.class_label,
                    rod,
                )
            )
    return writes, truths


def plan_estimates(writes: list, model_dir: Path) -> list[Estimate]:
    """The planned stream's final windows, cut with ideal reads, through the model."""
    from ext_sense_perception.data.device_stream import stream_windows
    from ext_sense_perception.errors import PerceptionError

    model, config = load(model_dir)
    windows, _, _ = stream_windows(writes, config)
    out = []
    for w in windows:
        with contextlib.suppress(PerceptionError):
            out.append(model.predict(w))
    return out


# ------------------------------------------------------------------------------ one run
def graph_args(task: Task, seed: int, trials: int, models: dict[str, Path], tmp: Path) -> dict:
    """The launch arguments of one live run (the condition's are added by the caller)."""
    from ext_sense.graphs import DEFAULT_SCENES

    args = {
        "sensor": SENSOR,
        "source": "sim",
        "seed": str(seed),
        "trials": str(trials),
        "model": str(models[task.task]),
        "port": str(tmp / f"{task.graph}.pty"),
        "scene": DEFAULT_SCENES[(task.task, SENSOR)],
    }
    if task is HANDOVER:
        args |= {
            "behaviours": "true",
            "sim_labels": "stable,unstable",
            "grasp_trials": str(GRASP_TRIALS),
            # an unstable grasp (or a stable one the rule never fires on) holds until this
            "handover_timeout_s": str(GRASP_TRIALS + 1.5),
        }
    return args


def live_run(
    task: Task,
    condition: str,
    args: dict[str, str],
    env: dict[str, str],
    tmp: Path,
) -> tuple[Path, dict[str, Any]]:
    """One recorded live run under ``condition``: its bag, and the :class:`RunResult` fields
    it gives (monitor summary, wall time, loads, the emulator's lateness)."""
    tag = f"{task.graph}_{condition.replace('+', '_')}"
    bag = tmp / f"{tag}_bag"
    topics = [SENSOR_PACKETS[SENSOR], TOPIC_GROUND_TRUTH, TOPIC_ESTIMATE]
    if task is HANDOVER:
        topics += [TOPIC_HANDOVER_OFFER, DECISION_TOPIC]
    trials = int(args["trials"])
    timeout = 60.0 + trials * (3.0 if task is HANDOVER else 1.5)
    before = loadavg()
    hog = start_hog(os.cpu_count() or 2) if _load(condition) == "loaded" else []
    t0 = time.monotonic()
    try:
        time.sleep(1.0 if hog else 0.0)
        gripper = gripper_emulator() if task is HANDOVER else contextlib.nullcontext()
        with recording(bag, topics, env, tmp / f"{tag}_record.log"), gripper as port:
            more = {"gripper_port": port} if port else {}
            summary = run_graph(task, args | more, env, tmp / f"{tag}.log", timeout)
        after = loadavg()
    finally:
        stop_hog(hog)
    return bag, {
        "monitor_summary": summary,
        "wall_s": time.monotonic() - t0,
        "load_before": before,
        "load_after": after,
        "emulator": emulator_lateness(tmp / f"{tag}.log"),
    }


def score_run(
    task: Task,
    condition: str,
    seed: int,
    trials: int,
    bag: Path,
    run: dict[str, Any],
    model_dir: Path,
    plan_cache: dict[tuple, tuple[list, list[Estimate]]],
) -> RunResult:
    """The three scores of one recorded run (``live_run``'s), on the trials its bag holds."""
    from ext_sense.graphs import DEFAULT_SCENES

    got = read_bag(bag)
    truths: list[GroundTruth] = got["truths"]
    if not truths:
        raise SystemExit(f"bench_live_offline: {bag} holds no ground truth (see the logs)")
    live = [e for e in got["estimates"] if not e.provisional]
    offline = bag_estimates(bag, model_dir)
    numbers = sorted(t.trial for t in truths)
    key = (task.task, seed, tuple(numbers))
    if key not in plan_cache:
        writes, ptruths = planned(DEFAULT_SCENES[(task.task, SENSOR)], seed, numbers)
        plan_cache[key] = (ptruths, plan_estimates(writes, model_dir))
    ptruths, pests = plan_cache[key]
    scores = [
        scoreboard_score(task, truths, live),
        scoreboard_score(task, truths, offline),
        scoreboard_score(task, ptruths, pests),
    ]
    releases = -1
    if task is HANDOVER:
        grasps = grasps_of(truths, got["offers"])
        for score, t, e in zip(
            scores, (truths, truths, ptruths), (live, offline, pests), strict=True
        ):
            release_fraction(score, t, e, grasps)
        releases = sum("OPEN_GRIPPER" in d for d in got["decisions"])
    return RunResult(
        task=task.task,
        condition=condition,
        seed=seed,
        trials_requested=trials,
        trial_numbers=numbers,
        live=scores[0],
        bag=scores[1],
        plan=scores[2],
        live_releases=releases,
        packets=got["packets"],
        packet_seq_gaps=got["seq_gaps"],
        **run,
    )


# ------------------------------------------------------------------------------ the table
def ratio(metric: str, live: float, offline: float) -> float:
    """live / offline for accuracy and fractions, offline / live for MAE: below 1 is worse."""
    if live == offline:  # 0 of N released both ways is equal, not undefined
        return 1.0
    if metric == "mae_cm":
        return offline / live if live > 0 else math.nan
    return live / offline if offline > 0 else math.nan


def rows(r: RunResult) -> list[dict[str, Any]]:
    """The table's rows of one run: each figure against both offline references."""
    metrics = ["mae_cm"] if r.task == TAP.task else ["accuracy", "release_fraction"]
    tol = TARGETS[_load(r.condition)]
    out = []
    for m in metrics:
        live = getattr(r.live, m)
        row: dict[str, Any] = {"task": r.task, "figure": m, "condition": r.condition, "live": live}
        for ref in ("bag", "plan"):
            off = getattr(getattr(r, ref), m)
            q = ratio(m, live, off)
            row[ref] = off
            row[f"ratio_{ref}"] = q
            row[f"within_{ref}"] = bool(abs(1.0 - q) <= tol) if math.isfinite(q) else False
        row["target"] = tol
        out.append(row)
    return out


def print_table(results: Sequence[RunResult]) -> None:
    """The side-by-side table: live, both offline references, ratios and the targets."""
    print(
        "\ntask               figure            condition        |   live |    bag   ratio ok"
        " |   plan   ratio ok | target"
    )
    for r in results:
        for row in rows(r):
            cells = [f"{row['live']:6.3f}"]
            for ref in ("bag", "plan"):
                ok = "yes" if row[f"within_{ref}"] else "NO "
                cells.append(f"{row[ref]:6.3f}  {row[f'ratio_{ref}']:5.2f}  {ok}")
            print(
                f"{row['task']:18s} {row['figure']:17s} {row['condition']:16s} | "
                + " | ".join(cells)
                + f" | {100 * row['target']:.0f}%"
            )
    print(
        "\nper run: trials in the bag, scored live/bag/plan, stable grasps released "
        "live/bag/plan, live gripper opens, packets (seq gaps), load before -> after, the "
        "emulated sensor's late writes"
    )
    for r in results:
        s = (
            f"{r.live.scored}/{r.bag.scored}/{r.plan.scored} of {len(r.trial_numbers)} "
            f"({r.live.degraded} degraded live)"
        )
        g = ""
        if r.task == HANDOVER.task:
            g = (
                f"; stable grasps released {r.live.released_grasps}/{r.bag.released_grasps}/"
                f"{r.plan.released_grasps} of {r.live.stable_grasps}; gripper opened "
                f"{r.live_releases}x"
            )
        print(
            f"  {r.task:18s} {r.condition:16s} {s}{g}; packets {r.packets} "
            f"({r.packet_seq_gaps} lost); {r.wall_s:.0f} s; load {r.load_before.split()[0]}"
            f" -> {r.load_after.split()[0]}; monitor: {r.monitor_summary or '-'}; "
            f"emulator: {r.emulator or '-'}"
        )


# ------------------------------------------------------------------------------ main
def _load(condition: str) -> str:
    """The load of a condition (``quiet`` or ``loaded``), the part before any ``+``."""
    return condition.split("+")[0]


def check_condition(condition: str) -> None:
    """Refuse a condition this bench cannot run, naming what is wrong."""
    load, *mods = condition.split("+")
    if load not in TARGETS or any(m not in MODIFIERS for m in mods):
        raise SystemExit(
            f"--conditions: {condition!r} is not a load ({', '.join(TARGETS)}) followed by "
            f"optional +modifiers ({', '.join(MODIFIERS)})"
        )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer trials, quiet and loaded")
    parser.add_argument("--taps", type=int, default=0, help="tap trials per run (default 30)")
    parser.add_argument("--grasps", type=int, default=0, help="handover grasps per run (10)")
    parser.add_argument("--seed", type=int, default=11, help="simulator seed of every run")
    parser.add_argument("--conditions", default="", help="comma separated (default: all)")
    parser.add_argument("--models", type=Path, help="model directory (created when missing)")
    parser.add_argument("--domain", type=int, default=44, help="ROS_DOMAIN_ID of the graphs")
    parser.add_argument("--json", type=Path, help="also write every figure here")
    parser.add_argument("--keep", action="store_true", help="keep the bags and logs")
    args = parser.parse_args()
    taps = args.taps or (6 if args.quick else 30)
    grasps = args.grasps or (2 if args.quick else 10)
    conditions = ["quiet", "loaded"] + ([] if args.quick else ["loaded+priority"])
    if args.conditions:
        conditions = [c for c in args.conditions.split(",") if c]
    for condition in conditions:
        check_condition(condition)
    env = dict(os.environ, ROS_DOMAIN_ID=str(args.domain), PYTHONUNBUFFERED="1")
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"  # the children's traffic stays here
    tmp = Path(tempfile.mkdtemp(prefix="bench_live_offline_"))
    print(
        f"[live-offline] {taps} taps, {grasps} grasps of {GRASP_TRIALS} trials, seed "
        f"{args.seed}, conditions {conditions}; {os.cpu_count()} cores; "
        f"ROS_DOMAIN_ID={args.domain}; {tmp}",
        flush=True,
    )
    t0 = time.monotonic()
    models = ensure_models(args.models or tmp / "models")
    print(f"[live-offline] models ready in {time.monotonic() - t0:.0f} s", flush=True)
    results: list[RunResult] = []
    plan_cache: dict[tuple, tuple[list, list[Estimate]]] = {}
    try:
        for condition in conditions:
            for task, n in ((TAP, taps), (HANDOVER, grasps * GRASP_TRIALS)):
                a = graph_args(task, args.seed, n, models, tmp)
                if "+priority" in condition:
                    a["reader_priority"] = str(PRIORITY)
                if "+one_process" in condition:
                    a["hot_path"] = "one_process"
                print(f"[live-offline] {task.graph} {condition}: load {loadavg()}", flush=True)
                bag, run = live_run(task, condition, a, env, tmp)
                r = score_run(
                    task, condition, args.seed, n, bag, run, models[task.task], plan_cache
                )
                results.append(r)
                for row in rows(r):
                    print(
                        f"[live-offline]   {row['figure']}: live {row['live']:.3f}, bag "
                        f"{row['bag']:.3f}, plan {row['plan']:.3f} ({r.wall_s:.0f} s)",
                        flush=True,
                    )
    finally:
        if not args.keep:
            import shutil

            shutil.rmtree(tmp, ignore_errors=True)
    print_table(results)
    print(f"[live-offline] total {time.monotonic() - t0:.0f} s", flush=True)
    if args.json:
        payload = [asdict(r) | {"rows": rows(r)} for r in results]
        args.json.write_text(json.dumps(payload, indent=1, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The ``contact_window`` node's parameters, and the window configuration and liveness they give.

Windows are cut by the model card's task profile (what training cut the model's windows with),
else the task's own; the parameters choose task, sensor, model, BioTac slots and the liveness
and stuck-taxel judgement, never the profile. Pure: no rclpy.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Protocol

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.liveness import StreamLiveness
from ext_sense_perception.online.model_card import read_card
from ext_sense_perception.online.model_store import locate_model
from ext_sense_perception.online.window import NUSKIN_TAXELS, WindowConfig
from ext_sense_runtime.enums import Sensor
from ext_sense_runtime.parameters import param
from ext_sense_runtime.stamps import MS

EXPECTED_RATE_HZ = {Sensor.NUSKIN: 1000.0, Sensor.BIOTAC: 100.0}
"""Packets per second each sensor's driver sends while streaming (its drains)."""


class Log(Protocol):
    """Where the choice of profile is said (a node's logger)."""

    def info(self, message: str) -> object:
        """Say which profile cuts the windows."""

    def warning(self, message: str) -> object:
        """Say why the card's profile was not used."""


@dataclass(frozen=True)
class WindowParameters:
    """``contact_window``'s parameters, all read-only."""

    task: str = param(
        "tap_localization",
        "Task: tap_localization, handover_stability or food_identification.",
        read_only=True,
    )
    sensor: str = param("nuskin", "Sensor: nuskin or biotac.", read_only=True)
    model_path: str = param(
        "",
        "Model bundle whose card's task profile cuts the windows (window, sample, anytime "
        "times, debounce, onset detector): a directory, or a model name looked up as "
        "contact_inference does (empty: the task's default model, <task>_<sensor>); without a "
        "readable card, the task's own profile.",
        read_only=True,
    )
    sensor_ids: tuple[int, ...] = param(
        (),
        "BioTac sensor slots joined into one window (channels in this order); empty: as many "
        "slots from 0 as the model card's window has channels (slot 0 without a card).",
        read_only=True,
    )
    activity_min_taxels: int = param(
        WindowConfig.activity_min_taxels,
        "NUSkin onset: distinct taxels the onset's events must come from (one taxel at its "
        "ceiling is a fault, not a contact).",
        low=1,
        high=NUSKIN_TAXELS,
        read_only=True,
    )
    stuck_rate_hz: float = param(
        WindowConfig.stuck_rate_hz,
        "NUSkin: events per second of one taxel that count as its ceiling, Hz.",
        low=1.0,
        high=1e6,
        read_only=True,
    )
    stuck_after_ms: float = param(
        WindowConfig.stuck_after_ns / MS,
        "NUSkin: a taxel at stuck_rate_hz for longer than this is stuck: WARN on /diagnostics, "
        "masked from onset detection until it quiets, its windows degraded, ms.",
        low=100.0,
        high=600000.0,
        read_only=True,
    )
    expected_rate_hz: float = param(
        0.0,
        "Packets per second the input has while streaming (the driver's drains), Hz; 0: the "
        "sensor's (NUSkin 1000, BioTac 100).",
        low=0.0,
        high=100000.0,
        read_only=True,
    )
    stall_warn_ms: float = param(
        100.0,
        "Silence of the input while streaming that is a stall (WARN, windows across it "
        "degraded), ms.",
        low=1.0,
        high=60000.0,
        read_only=True,
    )
    stall_error_ms: float = param(
        500.0,
        "Silence of the input while streaming that is an ERROR, ms.",
        low=1.0,
        high=60000.0,
        read_only=True,
    )
    late_ms: float = param(
        100.0,
        "A message arriving this much later than the stream's usual delay is late, ms: "
        "counted on /diagnostics, its windows not degraded (a window closes on data past "
        "its end, so a late packet inside it is in it).",
        low=1.0,
        high=60000.0,
        read_only=True,
    )


def window_config(p: WindowParameters, log: Log) -> tuple[WindowConfig, tuple[int, ...], str]:
    """The window configuration (the model card's profile, else the task's), BioTac slots, source.

    The source is the card's path, or ``"task"``. A bad task, sensor or stuck-taxel setting is a
    ValueError naming it.
    """
    try:
        config = WindowConfig.for_task(p.task, p.sensor)
    except PerceptionError as err:
        raise ValueError(f"contact_window: {err}") from err
    source, channels = "task", 1
    try:
        path = locate_model(p.model_path, p.task, p.sensor)
        card = read_card(path)
    except PerceptionError as err:
        log.info(f"task profile of {p.task} (no model card: {err})")
    else:
        if card.task != config.task.label or card.sensor != config.sensor.label:
            log.warning(
                f"model card {path} is for {card.task}/{card.sensor}: using the task profile"
            )
        else:
            config = WindowConfig.for_profile(card.profile, config.sensor)
            source, channels = str(path), int(card.window.n_channels)
    try:
        config = replace(
            config,
            activity_min_taxels=p.activity_min_taxels,
            stuck_rate_hz=p.stuck_rate_hz,
            stuck_after_ns=round(p.stuck_after_ms * MS),
        )
    except PerceptionError as err:
        raise ValueError(f"contact_window: {err}") from err
    # one PAC channel per BioTac: a model trained on both fingers takes slots 0 and 1
    biotac = config.sensor is Sensor.BIOTAC and channels
    default_ids = tuple(range(channels)) if biotac else (0,)
    return config, p.sensor_ids or default_ids, source


def input_liveness(p: WindowParameters, config: WindowConfig, topic: str) -> StreamLiveness:
    """The input's liveness: its expected rate, stall and lateness thresholds."""
    liveness = StreamLiveness(
        topic,
        p.expected_rate_hz or EXPECTED_RATE_HZ[config.sensor],
        warn_ns=round(p.stall_warn_ms * MS),
        error_ns=round(p.stall_error_ms * MS),
        late_ns=round(p.late_ms * MS),
    )
    if config.sensor is Sensor.NUSKIN and not config.external_onsets:
        liveness.contact_words = int(config.activity_min_events)
        # by then every window that could cover a gap has been cut (its onset at the latest
        # pre_ns after the gap, its end post_ns later), with 100 ms to spare
        liveness.contact_horizon_ns = max(config.pre_ns, 0) + config.post_ns + 100 * MS
        liveness.debounce_ns = config.debounce_ns
    return liveness

"""The ``contact_window`` node's parameters: the window configuration and the input's liveness.

Kept out of the node module so that it stays about moving messages; the values are declared
with descriptors (units, ranges, read-only) as every node of the project does.
"""

from __future__ import annotations

from dataclasses import replace

from rclpy.node import Node

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.liveness import StreamLiveness
from ext_sense_perception.online.model_card import read_card
from ext_sense_perception.online.model_store import locate_model
from ext_sense_perception.online.window import WindowConfig
from ext_sense_runtime.enums import Sensor
from ext_sense_runtime.parameters import declare
from ext_sense_runtime.stamps import MS, US


def declare_window_config(node: Node) -> tuple[WindowConfig, tuple[int, ...], str]:
    """Declare the task, sensor, model and window parameters.

    Returns:
        The window configuration (the model card's task profile with the overrides), the
        BioTac sensor slots joined into one window, and where the profile came from.

    Raises:
        ValueError: A bad task, sensor or window setting (the message names it).
    """
    task = declare(
        node,
        "task",
        "tap_localization",
        "Task: tap_localization, handover_stability or food_identification.",
        read_only=True,
    )
    sensor = declare(node, "sensor", "nuskin", "Sensor: nuskin or biotac.", read_only=True)
    model_path = declare(
        node,
        "model_path",
        "",
        "Model bundle whose card's task profile cuts the windows: a directory, or a model "
        "name looked up as contact_inference does (empty: the task's default model, "
        "<task>_<sensor>); without a readable card, the task's own profile.",
        read_only=True,
    )
    base, profile_source, card_channels = _base_config(node, task, sensor, model_path)
    pre_ms = declare(
        node,
        "pre_onset_ms",
        base.pre_ns / MS,
        "Signal kept before the onset, ms (negative: the window starts after it).",
        low=-60000.0,
        high=10000.0,
        read_only=True,
    )
    post_ms = declare(
        node,
        "post_onset_ms",
        base.post_ns / MS,
        "Signal after the onset in the final window, ms.",
        low=1.0,
        high=60000.0,
        read_only=True,
    )
    sample_us = declare(
        node,
        "sample_us",
        base.profile.sample_ns / US,
        "NUSkin window sample (bin of signed event counts), microseconds.",
        low=10.0,
        high=1_000_000.0,
        read_only=True,
    )
    prov = declare(
        node,
        "anytime_post_ms",
        [p / MS for p in base.anytime_post_ns],
        "Post-onset times of the provisional (anytime) windows, ms; empty: none.",
        read_only=True,
    )
    debounce_ms = declare(
        node,
        "debounce_ms",
        base.debounce_ns / MS,
        "Minimum time between two onsets, ms.",
        low=0.0,
        high=60000.0,
        read_only=True,
    )
    min_events = declare(
        node,
        "activity_min_events",
        base.activity_min_events,
        "NUSkin onset: events within activity_window_ms that mean contact.",
        low=1,
        high=100000,
        read_only=True,
    )
    act_ms = declare(
        node,
        "activity_window_ms",
        base.activity_window_ns / MS,
        "NUSkin onset: sliding window events are counted in, ms.",
        low=0.01,
        high=1000.0,
        read_only=True,
    )
    min_taxels = declare(
        node,
        "activity_min_taxels",
        base.activity_min_taxels,
        "NUSkin onset: distinct taxels those events must come from (one taxel at its ceiling "
        "is a fault, not a contact).",
        low=1,
        high=base.n_taxels,
        read_only=True,
    )
    stuck_rate = declare(
        node,
        "stuck_rate_hz",
        base.stuck_rate_hz,
        "NUSkin: events per second of one taxel that count as its ceiling, Hz.",
        low=1.0,
        high=1e6,
        read_only=True,
    )
    stuck_ms = declare(
        node,
        "stuck_after_ms",
        base.stuck_after_ns / MS,
        "NUSkin: a taxel at stuck_rate_hz for longer than this is stuck: WARN on /diagnostics, "
        "masked from onset detection until it quiets, its windows degraded, ms.",
        low=100.0,
        high=600000.0,
        read_only=True,
    )
    sensor_ids = declare(
        node,
        "sensor_ids",
        # one PAC channel per BioTac: a model trained on both fingers takes slots 0 and 1
        list(range(card_channels)) if base.sensor is Sensor.BIOTAC and card_channels else [0],
        "BioTac sensor slots joined into one window (channels in this order); default: as many "
        "slots from 0 as the model card's window has channels.",
        read_only=True,
    )
    try:
        config = replace(
            base.with_profile(
                pre_ns=round(pre_ms * MS),
                post_ns=round(post_ms * MS),
                sample_ns=round(sample_us * US),
                anytime_post_ns=tuple(round(p * MS) for p in prov),
                debounce_ns=round(debounce_ms * MS),
            ),
            activity_min_events=int(min_events),
            activity_window_ns=round(act_ms * MS),
            activity_min_taxels=int(min_taxels),
            stuck_rate_hz=float(stuck_rate),
            stuck_after_ns=round(stuck_ms * MS),
        )
    except PerceptionError as err:
        raise ValueError(f"contact_window: {err}") from err
    return config, tuple(int(s) for s in sensor_ids), profile_source


def _base_config(
    node: Node, task: str, sensor: str, model_path: str
) -> tuple[WindowConfig, str, int | None]:
    """The window configuration of the model's card, else of the task.

    Returns:
        The configuration, where it came from, and the card's window channels (``None``
        without a usable card).
    """
    try:
        config = WindowConfig.for_task(task, sensor)
    except PerceptionError as err:
        raise ValueError(f"contact_window: {err}") from err
    try:
        path = locate_model(model_path, task, sensor)
        card = read_card(path)
    except PerceptionError as err:
        node.get_logger().info(f"task profile of {task} (no model card: {err})")
        return config, "task", None
    if card.task != config.task.label or card.sensor != config.sensor.label:
        node.get_logger().warning(
            f"model card {path} is for {card.task}/{card.sensor}: using the task profile"
        )
        return config, "task", None
    for_card = WindowConfig.for_profile(card.profile, config.sensor)
    return for_card, str(path), int(card.window.n_channels)


def declare_input_liveness(node: Node, config: WindowConfig, input_topic: str) -> StreamLiveness:
    """Declare the input's expected rate, stall and lateness thresholds; the liveness they give."""
    liveness = StreamLiveness(
        input_topic,
        declare(
            node,
            "expected_rate_hz",
            1000.0 if config.sensor is Sensor.NUSKIN else 100.0,
            "Packets per second the input has while streaming (the driver's drains), Hz.",
            low=0.1,
            high=100000.0,
            read_only=True,
        ),
        warn_ns=round(
            declare(
                node,
                "stall_warn_ms",
                100.0,
                "Silence of the input while streaming that is a stall (WARN, windows "
                "across it degraded), ms.",
                low=1.0,
                high=60000.0,
                read_only=True,
            )
            * MS
        ),
        error_ns=round(
            declare(
                node,
                "stall_error_ms",
                500.0,
                "Silence of the input while streaming that is an ERROR, ms.",
                low=1.0,
                high=60000.0,
                read_only=True,
            )
            * MS
        ),
        late_ns=round(
            declare(
                node,
                "late_ms",
                100.0,
                "A message arriving this much later than the stream's usual delay is late, ms: "
                "counted on /diagnostics, its windows not degraded (a window closes on data past "
                "its end, so a late packet inside it is in it).",
                low=1.0,
                high=60000.0,
                read_only=True,
            )
            * MS
        ),
    )
    if config.sensor is Sensor.NUSKIN and not config.external_onsets:
        liveness.contact_words = int(config.activity_min_events)
        # by then every window that could cover a gap has been cut (its onset at the latest
        # pre_ns after the gap, its end post_ns later), with 100 ms to spare
        liveness.contact_horizon_ns = max(config.pre_ns, 0) + config.post_ns + 100 * MS
        liveness.debounce_ns = config.debounce_ns
    return liveness

"""``sim_device``: an emulated NUSkin or BioTac streaming a scene's bytes in real time.

Streams over a pty (with a symlink at ``port_link`` so a driver's ``port`` can name it before
it exists) or a python-can virtual channel, from a thread, and publishes ``ground_truth``
(``ext_sense_msgs/ContactGroundTruth``) stamped with the host time at which each trial's
true onset bytes were written.
"""

from __future__ import annotations

import threading

from rclpy.node import Node

from ext_sense_msgs.msg import ContactGroundTruth
from ext_sense_runtime.diagnostics import Level, Updater
from ext_sense_runtime.diagnostics_ros import DiagnosticsPublisher
from ext_sense_runtime.node_main import run_node
from ext_sense_runtime.parameters import declare
from ext_sense_runtime.qos import GROUND_TRUTH_QOS
from ext_sense_runtime.stamps import fill_stamp
from ext_sense_sim.scene import load_scene
from ext_sense_sim.streaming import GroundTruth, StreamStats, open_link, stream


class SimDeviceNode(Node):
    """Emulated tactile device (see module docstring)."""

    def __init__(self, **kwargs: object) -> None:
        super().__init__("sim_device", **kwargs)
        device = declare(
            self, "device", "nuskin", "Emulated sensor: nuskin or biotac.", read_only=True
        )
        scene_name = declare(
            self,
            "scene",
            "",
            "Shipped scene name or scene file path (empty: the 30 cm rod taps of the device).",
            read_only=True,
        )
        link = declare(self, "link", "pty", "Link: pty or can.", read_only=True)
        port_link = declare(
            self,
            "port_link",
            "",
            "Path of a symlink to create to the pty (empty: none).",
            read_only=True,
        )
        can_channel = declare(
            self, "can_channel", "ext_sense", "python-can virtual channel.", read_only=True
        )
        trials = declare(
            self,
            "trials",
            0,
            "Trials to stream (0 = forever).",
            low=0,
            high=1_000_000,
            read_only=True,
        )
        seed = declare(
            self, "seed", 0, "Seed of the stream.", low=0, high=2**31 - 1, read_only=True
        )
        period = declare(
            self,
            "trial_period_s",
            1.0,
            "Time between trial starts, s.",
            low=0.01,
            high=3600.0,
            read_only=True,
        )
        default = {"nuskin": "tap_rod30_nuskin", "biotac": "tap_rod30_biotac"}
        if device not in default:
            raise ValueError(f"The 'device' parameter must be nuskin or biotac. Got {device!r}.")
        self.scene = load_scene(scene_name or default[device])
        if self.scene.sensor.label != device:
            raise ValueError(
                f"The 'scene' parameter names a {self.scene.sensor.label} scene "
                f"({self.scene.name}) but 'device' is {device!r}."
            )
        self.sink = open_link(link, link_path=port_link, can_channel=can_channel)
        self.port = getattr(self.sink, "path", f"can:{can_channel}")
        self.pub = self.create_publisher(ContactGroundTruth, "ground_truth", GROUND_TRUTH_QOS)
        self.stats = StreamStats()
        self.error = ""
        self._stop = threading.Event()
        updater = Updater(self.port)
        updater.add_check("stream", self._check)
        self.diagnostics = DiagnosticsPublisher(self, updater)
        self._thread = threading.Thread(
            target=self._run, args=(seed, trials, period), name="sim_device", daemon=True
        )
        self._thread.start()
        self.get_logger().info(f"streaming scene {self.scene.name} on {self.port}")

    def _run(self, seed: int, trials: int, period: float) -> None:
        try:
            self.stats = stream(
                self.scene,
                self.sink.write,
                seed=seed,
                trials=trials,
                period_s=period,
                on_onset=self._publish,
                stop=self._stop,
            )
        except Exception as err:
            self.error = repr(err)
            self.get_logger().error(f"stream stopped: {err!r}")

    def _publish(self, gt: GroundTruth) -> None:
        msg = ContactGroundTruth(
            task=gt.task,
            trial=gt.trial,
            tap_position_m=gt.tap_position_m,
            rod_length_m=gt.rod_length_m,
            class_label=gt.class_label,
        )
        fill_stamp(msg.header.stamp, gt.stamp_ns)
        msg.header.frame_id = self.scene.sensor.label
        self.pub.publish(msg)
        self.stats.trials = gt.trial + 1

    def _check(self) -> tuple[Level, str, dict[str, object]]:
        if self.error:
            return Level.ERROR, self.error, {}
        return (
            Level.OK,
            "streaming",
            {"trials": self.stats.trials, "dropped_bytes": getattr(self.sink, "dropped_bytes", 0)},
        )

    def destroy_node(self) -> None:
        """Stop the stream thread and close the link."""
        self._stop.set()
        self._thread.join(timeout=2.0)
        self.sink.close()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Run the node until shutdown."""
    return run_node(SimDeviceNode, args)

"""The Foxglove layout shipped with the package, built here so that it names the view's channels.

``foxglove_layout.json`` is this module's output (a test keeps the two equal; ``python -m
ext_sense.view.layout`` rewrites it). The panels on the graph's own topics fill from a recorded
bag too; the picture panels fill live, or from ``ext-sense replay`` with the view.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import foxglove.layouts as fl

from ext_sense.topics import TOPIC_DIAGNOSTICS, TOPIC_ESTIMATE, TOPIC_GROUND_TRUTH
from ext_sense.view import channels as ch

LAYOUT_PATH = Path(__file__).with_name("foxglove_layout.json")


def _image(topic: str, title: str) -> fl.ImagePanel:
    return fl.ImagePanel(
        title=title, config=fl.ImageConfig(image_mode=fl.ImageModeConfig(image_topic=topic))
    )


def _item(content: object, proportion: float = 1.0) -> fl.SplitItem:
    return fl.SplitItem(proportion=proportion, content=content)


def build_layout() -> fl.Layout:
    """The layout: pictures on top, plots and numbers below."""
    pictures = fl.SplitContainer(
        direction="row",
        items=[
            _item(_image(ch.TAXELS, "Taxels (rate, log scale; X dead, white frame saturated)")),
            _item(_image(ch.WINDOW, "Contact window (taxels x time, red: onset)"), 1.5),
            _item(_image(ch.ESTIMATE, "Estimate (orange) and truth (green)")),
        ],
    )
    rates = fl.PlotPanel(
        title="Event rate per finger / BioTac PAC",
        config=fl.PlotConfig(
            paths=[
                fl.PlotSeries(value=f"{ch.RATES}.left_events_per_s", label="left finger, ev/s"),
                fl.PlotSeries(value=f"{ch.RATES}.right_events_per_s", label="right finger, ev/s"),
            ],
            time_window_mode="sliding",
            following_view_width=20.0,
        ),
    )
    pac = fl.PlotPanel(
        title="BioTac PAC, last second",
        config=fl.PlotConfig(
            paths=[
                fl.PlotSeries(value=f"{ch.PAC}.pac_0[:]", label="sensor 0"),
                fl.PlotSeries(value=f"{ch.PAC}.pac_1[:]", label="sensor 1"),
            ],
            x_axis_val="index",
        ),
    )
    taps = fl.PlotPanel(
        title="Tap position: estimate vs truth, m",
        config=fl.PlotConfig(
            paths=[
                fl.PlotSeries(value=f"{TOPIC_ESTIMATE}.tap_position_m", label="estimate"),
                fl.PlotSeries(value=f"{TOPIC_GROUND_TRUTH}.tap_position_m", label="truth"),
            ],
        ),
    )
    numbers = fl.RawMessagesPanel(
        title="Latest estimate", config=fl.RawMessagesConfig(topic_path=ch.ESTIMATE_INFO)
    )
    diagnostics = fl.DiagnosticsSummaryPanel(
        title="Diagnostics",
        config=fl.DiagnosticsSummaryConfig(topic_to_render=TOPIC_DIAGNOSTICS, sort_by_level=True),
    )
    plots = fl.SplitContainer(
        direction="row",
        items=[
            _item(
                fl.TabContainer(
                    tabs=[
                        fl.TabItem(title="NUSkin", content=rates),
                        fl.TabItem(title="BioTac", content=pac),
                    ]
                )
            ),
            _item(taps),
            _item(numbers),
            _item(diagnostics),
        ],
    )
    return fl.Layout(
        content=fl.SplitContainer(direction="column", items=[_item(pictures, 1.2), _item(plots)])
    )


def layout_json() -> str:
    """The layout as the shipped file holds it (indented, so that diffs read)."""
    return json.dumps(json.loads(build_layout().to_json()), indent=1, sort_keys=True) + "\n"


def main() -> int:
    """Rewrite the shipped layout file from :func:`build_layout`."""
    LAYOUT_PATH.write_text(layout_json())
    print(LAYOUT_PATH)
    return 0


if __name__ == "__main__":
    sys.exit(main())

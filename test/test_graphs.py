"""The launch files and ``ext-sense run`` derive from one graph description."""

from __future__ import annotations

import ast
import importlib.metadata
import importlib.util
import itertools
import os
import subprocess
import sys
from pathlib import Path

import pytest
from sim_models import write_card

from ext_sense.graph import GraphError, NodeSpec, launch_node_kwargs, parse_assignments
from ext_sense.graphs import GRAPHS, TOPIC_ESTIMATE

ROOT = Path(__file__).resolve().parents[1]
LAUNCH_DIR = ROOT / "launch"
LAUNCH_NAMES = {
    "tap_localization": "tap_localization.launch.py",
    "handover": "handover.launch.py",
    "food_identification": "food_identification.launch.py",
}


def _argument_combinations(graph_name):
    graph = GRAPHS[graph_name]
    for sensor, source, behaviours, monitor in itertools.product(
        ("nuskin", "biotac"), ("sim", "serial", "can", "bag"), ("true", "false"), ("true", "false")
    ):
        yield (
            graph,
            {
                "sensor": sensor,
                "source": source,
                "behaviours": behaviours,
                "monitor": monitor,
                "can_channel": "vcan0" if source == "can" else "",
            },
        )


def test_every_graph_has_a_launch_file_and_back():
    files = {p.name for p in LAUNCH_DIR.glob("*.launch.py")}
    assert files == set(LAUNCH_NAMES.values())
    assert set(GRAPHS) == set(LAUNCH_NAMES)


@pytest.mark.parametrize("graph_name", sorted(LAUNCH_NAMES))
def test_launch_file_only_delegates_to_the_shared_description(graph_name):
    tree = ast.parse((LAUNCH_DIR / LAUNCH_NAMES[graph_name]).read_text())
    funcs = [n for n in tree.body if isinstance(n, ast.FunctionDef)]
    assert [f.name for f in funcs] == ["generate_launch_description"]
    body = [s for s in funcs[0].body if not isinstance(s, ast.Expr)]  # drop the docstring
    assert len(body) == 1
    assert isinstance(body[0], ast.Return)
    call = body[0].value
    assert isinstance(call, ast.Call)
    assert call.func.id == "generate_launch_description_for"
    assert [a.value for a in call.args] == [graph_name]


@pytest.mark.parametrize("graph_name", sorted(GRAPHS))
def test_launch_actions_and_runner_start_the_same_nodes(graph_name):
    from ext_sense.runner import _node_kwargs

    for graph, overrides in _argument_combinations(graph_name):
        for spec in graph.nodes(overrides):
            launch_kwargs = launch_node_kwargs(spec, use_sim_time=False)
            runner_kwargs = _node_kwargs(spec, use_sim_time=False)
            runner_params = {p.name: p.value for p in runner_kwargs["parameter_overrides"]}
            assert launch_kwargs["parameters"] == [runner_params]
            cli = runner_kwargs["cli_args"]
            assert cli[0] == "--ros-args"
            assert cli[1::2] == ["-r"] * (len(cli) // 2)
            pairs = [tuple(r.split(":=")) for r in cli[2::2]]
            assert pairs[0] == ("__node", launch_kwargs["name"]) == ("__node", spec.name)
            assert launch_kwargs["remappings"] == pairs[1:] == list(spec.remappings)


@pytest.mark.parametrize("graph_name", sorted(GRAPHS))
def test_every_node_is_a_console_script_of_its_package_with_its_plugin(graph_name):
    scripts = {
        (ep.dist.name, ep.name): ep.value.split(":")[0]
        for ep in importlib.metadata.entry_points(group="console_scripts")
        if ep.dist is not None and ep.dist.name.startswith("ext_sense")
    }
    for graph, overrides in _argument_combinations(graph_name):
        for spec in graph.nodes(overrides):
            module = spec.plugin.split(":")[0]
            assert scripts.get((spec.package, spec.executable)) == module, spec


def test_estimates_are_published_on_the_documented_topic():
    assert TOPIC_ESTIMATE == "/extsense/contact_estimate"
    for graph in GRAPHS.values():
        inference = [n for n in graph.nodes() if n.executable == "contact_inference"]
        assert inference
        assert ("contact_estimate", TOPIC_ESTIMATE) in inference[0].remappings


def test_monitor_is_required_only_when_trials_are_bounded():
    graph = GRAPHS["tap_localization"]
    monitor = [n for n in graph.nodes({"trials": "5"}) if n.name == "estimate_monitor"]
    assert monitor[0].required
    monitor = [n for n in graph.nodes({"trials": "0"}) if n.name == "estimate_monitor"]
    assert not monitor[0].required


def test_bad_arguments_are_named():
    graph = GRAPHS["tap_localization"]
    with pytest.raises(GraphError, match="has no argument 'sensr'"):
        graph.nodes({"sensr": "nuskin"})
    with pytest.raises(GraphError, match="'sensor' argument must be one of"):
        graph.nodes({"sensor": "camera"})
    with pytest.raises(GraphError, match="name:=value"):
        parse_assignments(["sensor=nuskin"])


def test_node_spec_ros_args():
    spec = NodeSpec("p", "e", "n", "m:C", remappings=(("a", "/x/a"), ("b", "/x/b")))
    assert spec.ros_args() == ["--ros-args", "-r", "__node:=n", "-r", "a:=/x/a", "-r", "b:=/x/b"]
    assert NodeSpec("p", "e", "n", "m:C").ros_args() == ["--ros-args", "-r", "__node:=n"]


def test_cli_lists_subcommands_and_graphs():
    out = subprocess.run(
        [sys.executable, "-m", "ext_sense.cli", "--help"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    for command in (
        "run",
        "record",
        "replay",
        "demo",
        "nuskin",
        "biotac",
        "sim",
        "features",
        "train",
        "evaluate",
        "report",
    ):
        assert command in out, command
    out = subprocess.run(
        [sys.executable, "-m", "ext_sense.cli", "run", "--help"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    for graph in GRAPHS:
        assert graph in out


def test_run_dry_run_prints_the_graph():
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "ext_sense.cli",
            "run",
            "tap_localization",
            "--dry-run",
            "sensor:=biotac",
            "source:=serial",
            "port:=/dev/ttyACM0",
        ],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert "biotac_driver: ext_sense_drivers/biotac_driver" in out
    assert "port:='/dev/ttyACM0'" in out
    assert "sim_device" not in out


LAUNCH_ROS = importlib.util.find_spec("launch_ros") is not None


@pytest.mark.skipif(
    not LAUNCH_ROS, reason="launch_ros is not on PyPI; this check runs on a ROS 2 install"
)
@pytest.mark.parametrize("graph_name", sorted(LAUNCH_NAMES))
def test_launch_file_loads_with_launch_ros(graph_name, tmp_path):  # pragma: no cover - ROS only
    from launch import LaunchContext
    from launch.actions import DeclareLaunchArgument, OpaqueFunction
    from launch.utilities import normalize_to_list_of_substitutions, perform_substitutions

    from ext_sense.graph_model import ModelMissingError

    path = LAUNCH_DIR / LAUNCH_NAMES[graph_name]
    spec = importlib.util.spec_from_file_location("launch_file", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    description = module.generate_launch_description()
    declared = [e for e in description.entities if isinstance(e, DeclareLaunchArgument)]
    assert {d.name for d in declared} == {a.name for a in GRAPHS[graph_name].arguments}
    context = LaunchContext()
    for d in declared:
        d.visit(context)
    opaque = next(e for e in description.entities if isinstance(e, OpaqueFunction))
    # no usable model: the launch fails before any node action exists
    context.launch_configurations["model"] = "no_such_model_anywhere"
    with pytest.raises(ModelMissingError, match="ext-sense models create"):
        opaque.execute(context)
    task = _task_of(graph_name)
    model = write_card(tmp_path / "model", task)
    context.launch_configurations["model"] = str(model)
    nodes = opaque.execute(context)

    def text(value):  # node_name exists only once the action has run; package and executable
        return perform_substitutions(context, normalize_to_list_of_substitutions(value))

    expected = GRAPHS[graph_name].nodes({"model": str(model)})
    assert [(text(n.node_package), text(n.node_executable)) for n in nodes] == [
        (s.package, s.executable) for s in expected
    ]


def _task_of(graph_name):
    inference = [n for n in GRAPHS[graph_name].nodes() if n.executable == "contact_inference"]
    return inference[0].parameters["task"]


class _FakeLaunch:
    """Stand-ins for the few ``launch`` / ``launch_ros`` names ``launch_support`` uses, so its
    own logic (arguments, the model check, node actions) runs where ROS's launch is absent."""

    def __init__(self, monkeypatch):
        import types

        self.nodes = []
        fake = self

        class Entity:
            def __init__(self, *args, **kwargs):
                self.args, self.kwargs = args, kwargs

        class LaunchConfiguration(Entity):
            def perform(self, context):
                return context[self.args[0]]

        class Node(Entity):
            def __init__(self, **kwargs):
                super().__init__(**kwargs)
                fake.nodes.append(kwargs)

        names = {
            "launch": {"LaunchDescription": Entity},
            "launch.actions": {
                "DeclareLaunchArgument": Entity,
                "OpaqueFunction": Entity,
                "Shutdown": Entity,
            },
            "launch.substitutions": {"LaunchConfiguration": LaunchConfiguration},
            "launch_ros": {},
            "launch_ros.actions": {"Node": Node},
        }
        for name, attrs in names.items():
            monkeypatch.setitem(sys.modules, name, types.SimpleNamespace(**attrs))

    def run(self, graph_name, **values):
        """Build the description and run its OpaqueFunction with these argument values."""
        from ext_sense.launch_support import generate_launch_description_for

        description = generate_launch_description_for(graph_name)
        entities = description.args[0]
        declared = {e.args[0]: e.kwargs["default_value"] for e in entities[:-1]}
        assert set(declared) == {a.name for a in GRAPHS[graph_name].arguments}
        return entities[-1].kwargs["function"]({**declared, **values})


@pytest.mark.parametrize("graph_name", sorted(LAUNCH_NAMES))
def test_launch_support_refuses_without_a_model_before_any_node(graph_name, tmp_path, monkeypatch):
    from ext_sense.graph_model import ModelMissingError, with_model

    fake = _FakeLaunch(monkeypatch)
    with pytest.raises(ModelMissingError) as info:
        fake.run(graph_name, model="no_such_model_anywhere")
    assert fake.nodes == []
    # the same message as `ext-sense run` prints
    with pytest.raises(ModelMissingError) as direct:
        with_model(GRAPHS[graph_name], {"model": "no_such_model_anywhere"})
    assert str(info.value) == str(direct.value)
    assert "ext-sense models create" in str(info.value)
    assert "\n" not in str(info.value)
    # the task's default model found along the search path goes to both perception nodes
    monkeypatch.setenv("EXT_SENSE_MODELS", str(tmp_path))
    model = write_card(tmp_path / f"{_task_of(graph_name)}_nuskin", _task_of(graph_name))
    actions = fake.run(graph_name)
    assert len(actions) == len(fake.nodes) == len(GRAPHS[graph_name].nodes())
    perception = [n for n in fake.nodes if n["package"] == "ext_sense_perception"]
    assert [n["parameters"][0]["model_path"] for n in perception] == [str(model)] * 2


def test_with_model_checks_the_card_against_the_graph(tmp_path, monkeypatch):
    from ext_sense.graph_model import ModelMissingError, with_model

    monkeypatch.setenv("EXT_SENSE_MODELS", str(tmp_path))
    graph = GRAPHS["handover"]
    named = write_card(tmp_path / "my_handover", "handover_stability")
    assert with_model(graph, {"model": "my_handover"})["model"] == str(named)
    tap = write_card(tmp_path / "tap", "tap_localization")
    with pytest.raises(ModelMissingError, match=r"is for tap_localization/nuskin.*handover"):
        with_model(graph, {"model": str(tap)})
    with pytest.raises(ModelMissingError, match=r"is for handover_stability/nuskin.*biotac"):
        with_model(graph, {"model": str(named), "sensor": "biotac"})
    (tmp_path / "broken").mkdir()
    (tmp_path / "broken" / "model_card.json").write_text("{not json")
    with pytest.raises(ModelMissingError, match=r"not readable JSON.*models create"):
        with_model(graph, {"model": str(tmp_path / "broken")})


def test_run_refuses_without_a_model_in_one_line_before_any_node(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "EXT_SENSE_MODELS"}
    env["XDG_DATA_HOME"] = str(tmp_path / "data")
    out = subprocess.run(
        [sys.executable, "-m", "ext_sense.cli", "run", "food_identification", "model:=nope_xyz"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env=env,
        timeout=60,
    )
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr
    assert lines[0].startswith("ext-sense run: No model 'nope_xyz' for food_identification/nuskin")
    assert str(tmp_path / "data" / "ext_sense" / "models") in lines[0]
    assert "'ext-sense models create'" in lines[0]
    assert "[run] started" not in out.stderr + out.stdout

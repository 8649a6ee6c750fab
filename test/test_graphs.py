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


def test_estimates_are_published_on_the_documented_topics():
    """Final estimates alone on /extsense/contact_estimate, the anytime ones on their own topic;
    every reader of estimates gets both names remapped (a remapping matches a whole name)."""
    from ext_sense.topics import TOPIC_PROVISIONAL_ESTIMATE

    assert TOPIC_ESTIMATE == "/extsense/contact_estimate"
    assert TOPIC_PROVISIONAL_ESTIMATE == "/extsense/contact_estimate/provisional"
    both = {
        ("contact_estimate", TOPIC_ESTIMATE),
        ("contact_estimate/provisional", TOPIC_PROVISIONAL_ESTIMATE),
    }
    for name, graph in GRAPHS.items():
        inference = [n for n in graph.nodes() if n.executable == "contact_inference"]
        assert inference
        assert both <= set(inference[0].remappings)
        for _, overrides in _argument_combinations(name):
            for spec in graph.nodes(overrides):
                if any(rel == "contact_estimate" for rel, _ in spec.remappings):
                    assert both <= set(spec.remappings), spec


@pytest.mark.parametrize(
    ("source", "truth"), [("sim", True), ("bag", True), ("serial", False), ("can", False)]
)
def test_the_monitor_scores_against_ground_truth_only_where_there_is_some(source, truth):
    graph = GRAPHS["tap_localization"]
    extra = {"bag": "x.mcap"} if source == "bag" else {}
    nodes = graph.nodes({"source": source, "trials": "5", **extra})
    monitor = next(n for n in nodes if n.name == "estimate_monitor")
    assert monitor.parameters["ground_truth"] is truth
    assert monitor.parameters["expected"] == 5


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

        class LifecycleNode(Node):
            pass

        names = {
            "launch": {"LaunchDescription": Entity},
            "launch.actions": {
                "DeclareLaunchArgument": Entity,
                "OpaqueFunction": Entity,
                "Shutdown": Entity,
                "EmitEvent": Entity,
                "RegisterEventHandler": Entity,
            },
            "launch.events": {"matches_action": lambda action: ("matches", action)},
            "launch.substitutions": {"LaunchConfiguration": LaunchConfiguration},
            "launch_ros": {},
            "launch_ros.actions": {"Node": Node, "LifecycleNode": LifecycleNode},
            "launch_ros.event_handlers": {"OnStateTransition": Entity},
            "launch_ros.events": {},
            "launch_ros.events.lifecycle": {"ChangeState": Entity},
        }
        self.lifecycle_node_type = LifecycleNode
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
    actions = fake.run(graph_name, hot_path="processes")  # a Node action per node
    node_actions = [a for a in actions if "executable" in getattr(a, "kwargs", {})]
    assert len(node_actions) == len(fake.nodes) == len(GRAPHS[graph_name].nodes())
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


@pytest.mark.parametrize(
    ("argument", "message"),
    [
        ("trials:=abc", "The 'trials' argument must be an integer in [0, 1000000]. Got 'abc'"),
        ("trials:=-1", "The 'trials' argument must be an integer in [0, 1000000]. Got '-1'"),
        ("trials:=1.5", "The 'trials' argument must be an integer in [0, 1000000]. Got '1.5'"),
        ("baud:=abc", "The 'baud' argument must be an integer in [1, 100000000]. Got 'abc'"),
        ("seed:=xyz", "The 'seed' argument must be an integer in [0, 4294967295]. Got 'xyz'"),
        ("handover_timeout_s:=nan", "'handover_timeout_s' argument must be a number in [0.1,"),
        ("grasp_trials:=0", "The 'grasp_trials' argument must be an integer in [1, 1000]"),
        ("source:=bag", "The 'bag' argument must name an existing rosbag2 directory or"),
        ("port:=/nonexistent/x", "The 'port' argument must be a path in an existing, writable"),
        ("scene:=/nonexistent/scene.yaml", "The 'scene' argument must be a scene name or an"),
    ],
)
def test_bad_graph_arguments_are_refused_before_any_node_in_one_line(argument, message, tmp_path):
    graph = GRAPHS["handover"]
    overrides = parse_assignments([argument])
    with pytest.raises(GraphError) as info:
        graph.check_files(graph.resolve(overrides))
    assert message in str(info.value)
    out = subprocess.run(
        [sys.executable, "-m", "ext_sense.cli", "run", "handover", argument],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=60,
    )
    assert out.returncode == 2
    assert out.stderr.strip().splitlines() == [f"ext-sense run: {info.value}"]
    assert "[run]" not in out.stderr + out.stdout


def test_the_launch_file_refuses_bad_arguments_as_run_does(monkeypatch):
    fake = _FakeLaunch(monkeypatch)
    with pytest.raises(GraphError, match=r"The 'trials' argument must be an integer"):
        fake.run("tap_localization", trials="abc")
    with pytest.raises(GraphError, match=r"The 'bag' argument must name an existing"):
        fake.run("tap_localization", source="bag", bag="/nonexistent.mcap")
    assert fake.nodes == []


def _one_message_bag(path, topic, msg):
    from ext_sense_bags import BagWriter

    with BagWriter(path) as bag:
        bag.write(topic, 1_000_000_000, msg)
    return path


def test_good_numbers_and_existing_files_pass(tmp_path):
    from ext_sense_bags.messages import sensor_packet

    from ext_sense_drivers.packets import NUSKIN_WORDS_V1, PacketPacker

    graph = GRAPHS["handover"]
    packet = PacketPacker(NUSKIN_WORDS_V1).opened(1, 1_000_000_000)
    bag = _one_message_bag(tmp_path / "bag", "/extsense/nuskin/packets", sensor_packet(packet))
    values = graph.resolve({"trials": " 0", "seed": "4294967295", "handover_timeout_s": "2.5"})
    graph.check_files({**values, "port": str(tmp_path / "x.pty")})
    graph.check_files({**values, "source": "bag", "bag": str(bag)})
    graph.check_files({**values, "source": "serial", "port": "/dev/not_plugged_in_yet"})


def test_a_bag_without_packets_is_refused_naming_the_migration():
    """A bag of decoded arrays from before packets feeds no graph: it is migrated first."""
    import tempfile

    from ext_sense_bags import taxel_event_batch

    graph = GRAPHS["tap_localization"]
    values = graph.resolve({"source": "bag"})
    with tempfile.TemporaryDirectory() as tmp:
        batch = taxel_event_batch(1_000_000_000, [3], [1], [10], [0])
        old = _one_message_bag(Path(tmp) / "old", "/extsense/nuskin/events", batch)
        with pytest.raises(GraphError, match=r"ext-sense bag migrate .* OUT"):
            graph.check_files({**values, "bag": str(old)})
        empty = Path(tmp) / "empty"
        empty.mkdir()
        with pytest.raises(GraphError, match=r"holds no \.mcap"):
            graph.check_files({**values, "bag": str(empty)})


@pytest.mark.parametrize("manage", ["true", "false"])
def test_launch_drives_the_lifecycle_drivers_unless_told_not_to(manage, tmp_path, monkeypatch):
    """The driver is a LifecycleNode (with the namespace launch_ros requires); managed, the
    launch emits configure and registers activate on configuring -> inactive."""
    from lifecycle_msgs.msg import Transition

    fake = _FakeLaunch(monkeypatch)
    monkeypatch.setenv("EXT_SENSE_MODELS", str(tmp_path))
    write_card(tmp_path / "tap_localization_nuskin", "tap_localization")
    # the driver as a process of its own (in the default node_group its process manages it)
    actions = fake.run("tap_localization", manage_drivers=manage, hot_path="processes")
    drivers = [a for a in actions if isinstance(a, fake.lifecycle_node_type)]
    assert [d.kwargs["executable"] for d in drivers] == ["nuskin_driver"]
    assert drivers[0].kwargs["namespace"] == ""
    assert drivers[0].kwargs["parameters"][0]["autostart"] is False
    events = [a for a in actions if type(a).__name__ == "Entity" and "event" in a.kwargs]
    handlers = [a for a in actions if type(a).__name__ == "Entity" and not a.kwargs and a.args]
    if manage == "false":
        assert events == []
        assert handlers == []
        return
    configure = events[0].kwargs["event"].kwargs
    assert configure["transition_id"] == Transition.TRANSITION_CONFIGURE
    assert configure["lifecycle_node_matcher"] == ("matches", drivers[0])
    on_transition = handlers[0].args[0].kwargs
    assert on_transition["target_lifecycle_node"] is drivers[0]
    assert (on_transition["start_state"], on_transition["goal_state"]) == (
        "configuring",
        "inactive",
    )
    activate = on_transition["entities"][0].kwargs["event"].kwargs
    assert activate["transition_id"] == Transition.TRANSITION_ACTIVATE


def test_food_probe_drives_its_arm_through_franka_ros2_interfaces():
    graph = GRAPHS["food_identification"]
    nodes = graph.nodes({"behaviours": "true"})
    arm = next(s for s in nodes if s.executable == "sim_arm")
    food = next(s for s in nodes if s.executable == "food_behaviour")
    assert arm.package == "ext_sense_sim"
    assert food.parameters["arm"] == "franka"  # the adapter, against sim_arm's interfaces
    real = graph.nodes({"behaviours": "true", "arm": "franka"})
    assert all(s.executable != "sim_arm" for s in real)
    assert next(s for s in real if s.executable == "food_behaviour").parameters["arm"] == "franka"


@pytest.mark.parametrize("manage", ["true", "false"])
def test_gripper_is_a_lifecycle_node_managed_like_the_drivers(manage):
    nodes = GRAPHS["handover"].nodes({"behaviours": "true", "manage_drivers": manage})
    gripper = next(s for s in nodes if s.executable == "robotiq_gripper")
    driver = next(s for s in nodes if s.executable == "nuskin_driver")
    assert gripper.lifecycle
    assert gripper.parameters["autostart"] is False
    assert gripper.manage == driver.manage == (manage == "true")


@pytest.mark.parametrize("graph_name", sorted(GRAPHS))
def test_hot_path_one_process_groups_driver_window_and_inference(graph_name):
    from ext_sense.graph_process import HOT_PATH, process_groups

    graph = GRAPHS[graph_name]
    apart = graph.nodes({"hot_path": "processes"})
    assert all(len(specs) == 1 for _, specs in process_groups(apart))
    assert graph.nodes({"hot_path": "one_process"}) == graph.nodes()  # the default
    for source, hot in (
        ("sim", ["nuskin_driver", "contact_window", "contact_inference"]),
        ("bag", ["contact_window", "contact_inference"]),  # the bag player is the source
    ):
        nodes = graph.nodes({"hot_path": "one_process", "source": source})
        groups = dict(process_groups(nodes))
        assert [s.name for s in groups[HOT_PATH]] == hot
        # the other nodes keep a process each, and every node is started exactly once
        assert all(len(v) == 1 for k, v in groups.items() if k != HOT_PATH)
        assert sorted(s.name for v in groups.values() for s in v) == sorted(n.name for n in nodes)
        # otherwise the same nodes as with a process each
        assert [s.name for s in nodes] == [s.name for s in graph.nodes({"source": source})]


def test_a_process_group_round_trips_through_its_json_argument():
    import json

    from ext_sense.runner import _spec_from_json, group_payload

    nodes = GRAPHS["tap_localization"].nodes({"hot_path": "one_process", "model": "/m"})
    group = tuple(n for n in nodes if n.process)
    payload = json.loads(group_payload(group, use_sim_time=True))
    assert payload["use_sim_time"] is True
    assert tuple(_spec_from_json(raw) for raw in payload["specs"]) == group


def test_node_group_is_a_console_script_of_ext_sense():
    setup = (ROOT / "src" / "ext_sense" / "setup.py").read_text()
    assert '"node_group = ext_sense.runner:main"' in setup


@pytest.mark.parametrize("monitor", ["true", "false"])
def test_launch_starts_the_hot_path_as_one_node_group_action(monitor, tmp_path, monkeypatch):
    """One ``Node`` action of ``node_group`` (no name or remappings: they would apply to every
    node of the process), holding the driver, window and inference node specs."""
    import json

    fake = _FakeLaunch(monkeypatch)
    monkeypatch.setenv("EXT_SENSE_MODELS", str(tmp_path))
    write_card(tmp_path / "tap_localization_nuskin", "tap_localization")
    actions = fake.run("tap_localization", hot_path="one_process", monitor=monitor)
    groups = [a for a in actions if a.kwargs.get("executable") == "node_group"]
    assert len(groups) == 1
    kwargs = groups[0].kwargs
    assert kwargs["package"] == "ext_sense"
    assert not {"name", "parameters", "remappings"} & kwargs.keys()
    assert "on_exit" not in kwargs  # the required monitor is a process of its own
    specs = json.loads(kwargs["arguments"][0])["specs"]
    assert [s["name"] for s in specs] == ["nuskin_driver", "contact_window", "contact_inference"]
    assert specs[0]["lifecycle"]
    assert specs[0]["manage"]  # the group's process activates it
    assert specs[1]["parameters"]["model_path"] == str(tmp_path / "tap_localization_nuskin")
    # no LifecycleNode action nor lifecycle events: the driver is in the group
    assert not [a for a in actions if isinstance(a, fake.lifecycle_node_type)]
    others = [a.kwargs["executable"] for a in actions if a.kwargs.get("executable")]
    assert others == ["sim_device", "node_group"] + (
        ["estimate_monitor"] if monitor == "true" else []
    )

"""The interface packages built from ``interfaces/`` match upstream on the wire.

``control_msgs`` (and ``franka_msgs``) are not on PyPI, so ``scripts/setup.sh`` builds copies
of the definitions we use into the venv. A node of ours and a ROS install's controller only talk
if the type hashes (RIHS01) agree, so two independent checks:

- the copies are byte-identical to upstream: their git blob ids equal the ids upstream's tree
  holds at the pinned commit (``git ls-tree``);
- the hash of each type *as built into the venv* (read from its C type support, the value rmw
  puts on the wire) equals the hash rosidl computes from upstream's own text at that commit
  (``scripts/upstream_type_hashes.py``, run against a clone, output pasted below).

A changed copy, a dependency built differently (``sensor_msgs/JointState`` inside
``ParallelGripperCommand``), or a generator that hashes differently fails here.
"""

from __future__ import annotations

import ctypes
import hashlib
import importlib
import importlib.metadata
import json
import sysconfig
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def parse_hash_table(text: str) -> dict[str, str]:
    """``{type_name: hash}`` from lines alternating a type name and its indented hash."""
    lines = text.split()
    return dict(zip(lines[::2], lines[1::2], strict=True))


CONTROL_MSGS_COMMIT = "13dacdd8748264b6cd7cbbc9893c18c90e24be00"
"""ros-controls/control_msgs 6.8.0 (master, 2026-02-02). The three files are identical on the
``jazzy`` branch (f901df2), so the hashes hold for Jazzy and Kilted alike."""

CONTROL_MSGS_BLOBS = {
    "action/FollowJointTrajectory.action": "ddef4ee9dd79877120ee343dd89fe72dddf6dfa6",
    "action/GripperCommand.action": "171f7d09c5ef75a6df69895324372e387ca463f2",
    "action/ParallelGripperCommand.action": "90405b9a10f21e05c35f0983ef9e7b0c52d5f0fd",
    "msg/GripperCommand.msg": "bf137a3071fd67c2f52e65a90613f4fed2c148bf",
    "msg/JointComponentTolerance.msg": "9c4541ab51f8589cd3808a0cc5a392eb0db1f5e0",
    "msg/JointTolerance.msg": "43767db5478710016304148f50e27f54be965cba",
}

CONTROL_MSGS_HASHES = parse_hash_table(
    """
control_msgs/action/FollowJointTrajectory
    RIHS01_ff29901b2693f5deb847e96084a1c2cdb26e70b7c847be21859b70a55fb29cf0
control_msgs/action/FollowJointTrajectory_Feedback
    RIHS01_0bb018d181bdc6384dd75365480967bd1d6eaee4ef3dd597c64cd0b8bdc10867
control_msgs/action/FollowJointTrajectory_FeedbackMessage
    RIHS01_95618cc73912d99b9acaa17d2da5e832cb0bfdeede7534fa8ec600feca2a6c4b
control_msgs/action/FollowJointTrajectory_GetResult_Request
    RIHS01_ecf7ea8463d3beec7084bca75216d0b01b87b6e1e4e09679bb26093041efcbe9
control_msgs/action/FollowJointTrajectory_GetResult_Response
    RIHS01_08eefbaa146ce02ba45898d5e99160afd6c4c54a30d159aee0f2ca6035b1580f
control_msgs/action/FollowJointTrajectory_Goal
    RIHS01_8a9060704b269608f5a340934cc26e66869dd14bdac29e2e7fd9ec8b9882d205
control_msgs/action/FollowJointTrajectory_Result
    RIHS01_8002e99ed2c14c6faa522f2a93c26d744c5982f254f9e98ff9c6f19789bdb220
control_msgs/action/FollowJointTrajectory_SendGoal_Request
    RIHS01_179c93691f1f6d1d115881ff88c3917b7cc6eac2ba4bf56766cc7c4389e19ef1
control_msgs/action/FollowJointTrajectory_SendGoal_Response
    RIHS01_e6a48ba740ae254500129a877f0b071be8663a115da1a539b74599cc97921fbf
control_msgs/action/GripperCommand
    RIHS01_e17c0e644eccf14bea84a0a93e0977182872c2eb7873ca6694900059b46dbc84
control_msgs/action/GripperCommand_Feedback
    RIHS01_8f7c520077bab528bb9161ee3b83c81eee1f8aecadb8922ce82c79d667a819c4
control_msgs/action/GripperCommand_FeedbackMessage
    RIHS01_392ff03fcd872f9dc2405cbeb2897fcf011ad9998458b6aa85c603b8a49e431d
control_msgs/action/GripperCommand_Goal
    RIHS01_607d9f41eb241e1922e90f02125e87ae6bfb78f7f64a71dc92630263d01f8b6d
control_msgs/action/GripperCommand_Result
    RIHS01_bf512d5aa6a0e4fe4d8be22b2ec4a1973c3d250fa1f65e47450322c25c45c0a0
control_msgs/action/ParallelGripperCommand
    RIHS01_adfd3c1ebe8abc38ebcc0e454b6423d291d4010dd5697d14eca5b9be4726ae18
control_msgs/action/ParallelGripperCommand_Feedback
    RIHS01_ed6f7c4e5aea7f960432663c0e762e001a0a1f5cc0130d126e60041412d0543c
control_msgs/action/ParallelGripperCommand_FeedbackMessage
    RIHS01_c61f4cf99d06c5a3e24bed17c2910bdf66a30d89461e2ac7b5fd538a34b022cc
control_msgs/action/ParallelGripperCommand_Goal
    RIHS01_412807b6b6acf2bf406fb0cf3b5c8f84286cd4e4d425734155aa1ff41caa0063
control_msgs/action/ParallelGripperCommand_Result
    RIHS01_51acbcd62aa44097d3877c506eab1146856fa8768628ffbe102c1699152d2afa
control_msgs/action/ParallelGripperCommand_SendGoal_Request
    RIHS01_dc8e5d95c0e15af6f03ff237eb8cfdaac14cc2b09f51b363311e98ec0a8487a0
control_msgs/action/ParallelGripperCommand_SendGoal_Response
    RIHS01_613e4f060bff03b152eeaba1f8c6baa9d0309527b28b08bc9aae28ece7ef8b47
control_msgs/action/ParallelGripperCommand_GetResult_Request
    RIHS01_cea82415cadc3288fdfa8aaba509e9939732aaecac6edf9cb954e5a7161646ec
control_msgs/action/ParallelGripperCommand_GetResult_Response
    RIHS01_c973b1bb9b454de1c3f38a2af9d45bc1930b809f746d6d6ec91bb3c783cb09eb
control_msgs/msg/GripperCommand
    RIHS01_57eb8f326c9889ca8bb34ead82cc94cc09bf6bc5c3b6c09546dca3a00b589890
control_msgs/msg/JointComponentTolerance
    RIHS01_739ea7566931944d33830fa10f1bf5e7a7fbdc3172bce7a7eaac642bd6e3ffa4
control_msgs/msg/JointTolerance
    RIHS01_c254f9cece0f3b733017b6990fd46d1326e25242d6b8844398c97d9a88e7d648
"""
)
"""Printed by ``.venv/bin/python scripts/upstream_type_hashes.py CLONE
13dacdd8748264b6cd7cbbc9893c18c90e24be00 control_msgs control_msgs/action/GripperCommand.action
control_msgs/action/ParallelGripperCommand.action control_msgs/msg/GripperCommand.msg
control_msgs/action/FollowJointTrajectory.action control_msgs/msg/JointTolerance.msg
control_msgs/msg/JointComponentTolerance.msg`` (the script also prints the service and event
types of each action, which have no Python class of their own and are left out here)."""

CONTROL_MSGS_JAZZY_COMMIT = "f901df2662f22a39a06aa04a85a34602c47e3cc0"
"""ros-controls/control_msgs ``jazzy`` (2026-02-02): FollowJointTrajectory's feedback has no
``index``/``multi_dof_index`` there, so a Jazzy ``joint_trajectory_controller`` hashes the action
differently; ``scripts/setup.sh jazzy`` builds ``interfaces/jazzy/control_msgs/`` over the
master copy. The other files are identical on both branches."""

CONTROL_MSGS_JAZZY_BLOBS = {
    "action/FollowJointTrajectory.action": "dd0f809f6d9cf6d35fda4250787ef8f059f831c6",
}

CONTROL_MSGS_JAZZY_HASHES = parse_hash_table(
    """
control_msgs/action/FollowJointTrajectory
    RIHS01_738ebcb7a2d7cfa42f9f1001cc99ce3a4383d1cfe508015d9be8485e4b1c66f6
control_msgs/action/FollowJointTrajectory_Feedback
    RIHS01_3fd0aaecf71725121ae1ff7f01098a5e0da581e672be18a6b2c286cb43d96b49
control_msgs/action/FollowJointTrajectory_FeedbackMessage
    RIHS01_80398fcb9674a79081a9906e2ccf0c804dd7cb15e22e362e606ee87186beab71
"""
)
"""The hashes that differ on Jazzy, from the same script at ``CONTROL_MSGS_JAZZY_COMMIT`` (run in
the Kilted venv: the dependencies it reads, ``trajectory_msgs`` and ``builtin_interfaces``, have
the same definitions in both distributions)."""

FRANKA_MSGS_COMMIT = "29cb85a677b8f08888a0eb6f553ba89666ef64f7"
"""frankarobotics/franka_ros2 ``jazzy`` at v3.4.0 (2026-06-23), the newest commit holding
FrankaRobotState and SetFullCollisionBehavior. The six files have the same blob ids on the
``humble`` branch of the older frankaemika/franka_ros2 snapshot (40cf08b, v0.1.13, 2024-01-26),
so the hashes hold for either."""

FRANKA_MSGS_BLOBS = {
    "action/ErrorRecovery.action": "a845151cc840034a50f5fd010515d61e661f79ee",
    "msg/CollisionIndicators.msg": "03e92733f9e66fe1100ba61098c3d1149e16ab07",
    "msg/Elbow.msg": "d69eee910e075aac5f85444a2a423597020f6a6e",
    "msg/Errors.msg": "9eca9b41ba0af0f44f269b6f44ce07a76c75f385",
    "msg/FrankaRobotState.msg": "14dc9606fb84f750316083eef2d5347d3316b357",
    "srv/SetFullCollisionBehavior.srv": "c4d2b2dd00dc94816fb0e1e6d823f10e075da005",
}

FRANKA_MSGS_HASHES = parse_hash_table(
    """
franka_msgs/action/ErrorRecovery
    RIHS01_6c5dbf0517672f7127a92796e6a162d096e286c26f88c96177cb4c5448dfc5f5
franka_msgs/action/ErrorRecovery_Feedback
    RIHS01_bfca857376ec8a8e8a05de701d17e1998265937fab9e24a9123760c0b4e535c4
franka_msgs/action/ErrorRecovery_FeedbackMessage
    RIHS01_9aa39d034b40daa2fda2c313f086a9446e068705a8022d0fab2bb5b5e7edaf0e
franka_msgs/action/ErrorRecovery_GetResult_Request
    RIHS01_f8083ee58cef727487b211081c7ed1877fc0957afab42f2639531b70b244b914
franka_msgs/action/ErrorRecovery_GetResult_Response
    RIHS01_b05dfca7e4d9ff8afa2741cd98c8e090cc5a1266547e14e43967f9662952c922
franka_msgs/action/ErrorRecovery_Goal
    RIHS01_43889cf2d3c839922879a5d4714510313396d171b316893f21dd13675fb32fec
franka_msgs/action/ErrorRecovery_Result
    RIHS01_74997c44439ad72ba37cacdc39d968e34ca84cc8e18ab6b9d5b883b59e8aef8e
franka_msgs/action/ErrorRecovery_SendGoal_Request
    RIHS01_39a946d1c9f1a3e6766018e53f87806b6dce0e15490f0215e42b5b21d9d197a0
franka_msgs/action/ErrorRecovery_SendGoal_Response
    RIHS01_3a34425a9a1b2bd6d6cf1f90688a246f85681cb82c509521c85b9c6c70f039da
franka_msgs/msg/CollisionIndicators
    RIHS01_17d02113f0e8ec3768433baafd4f27fe5eaacf95d6c21f591bf3473e541e0840
franka_msgs/msg/Elbow
    RIHS01_f54141b92a05447bfa2f993ac28c289b477358a3d543ad099e1a34c10d70d9bb
franka_msgs/msg/Errors
    RIHS01_eaf7a9752f64efac239306101020545cebebff8b5130875d95bf0ed4d8bb774d
franka_msgs/msg/FrankaRobotState
    RIHS01_fd225b337bab54d06047858c866442b98e3a882a4717cefc6ddd783fcbf17332
franka_msgs/srv/SetFullCollisionBehavior
    RIHS01_43a5dafbb96eb1bd70872cdd6db23d4bf81bfb7a03e563349974f37e89cded15
franka_msgs/srv/SetFullCollisionBehavior_Request
    RIHS01_a2d516d986d35f9c21625659f95c99e76f86a15a909bfe1ce46ffbbd2d9e54d5
franka_msgs/srv/SetFullCollisionBehavior_Response
    RIHS01_44c69b6330cd839a5d91b276c3679a272650d591df9664315ef7f50e9f116caf
"""
)
"""Printed by ``.venv/bin/python scripts/upstream_type_hashes.py CLONE
29cb85a677b8f08888a0eb6f553ba89666ef64f7 franka_msgs franka_msgs/msg/FrankaRobotState.msg
franka_msgs/msg/CollisionIndicators.msg franka_msgs/msg/Elbow.msg franka_msgs/msg/Errors.msg
franka_msgs/srv/SetFullCollisionBehavior.srv franka_msgs/action/ErrorRecovery.action``."""


def on_jazzy() -> bool:
    """Whether this venv holds the Jazzy wheels (``make test-jazzy``)."""
    try:
        importlib.metadata.version("ros-jazzy-rclpy")
    except importlib.metadata.PackageNotFoundError:
        return False
    return True


def expected_hashes() -> dict[str, str]:
    """Every hash the built types must have, for this venv's distribution."""
    control = CONTROL_MSGS_HASHES | (CONTROL_MSGS_JAZZY_HASHES if on_jazzy() else {})
    return control | FRANKA_MSGS_HASHES


def _checked_types(table: dict[str, str]) -> list[str]:
    """The types of ``table`` with a Python class: parts of actions and services, messages."""
    return sorted(t for t in table if "_" in t.split("/")[-1] or "/msg/" in t)


class _TypeHash(ctypes.Structure):
    _fields_ = [("version", ctypes.c_uint8), ("value", ctypes.c_uint8 * 32)]


class _MessageTypeSupport(ctypes.Structure):
    """The head of ``rosidl_message_type_support_t`` (rosidl >= Iron)."""

    _fields_ = [
        ("typesupport_identifier", ctypes.c_char_p),
        ("data", ctypes.c_void_p),
        ("func", ctypes.c_void_p),
        ("get_type_hash_func", ctypes.CFUNCTYPE(ctypes.POINTER(_TypeHash), ctypes.c_void_p)),
    ]


def built_hash(msg_class: type) -> str:
    """The RIHS01 string the built C type support of ``msg_class`` reports."""
    type(msg_class).__import_type_support__()
    capsule = msg_class._TYPE_SUPPORT
    get_name = ctypes.pythonapi.PyCapsule_GetName
    get_name.restype, get_name.argtypes = ctypes.c_char_p, [ctypes.py_object]
    get_pointer = ctypes.pythonapi.PyCapsule_GetPointer
    get_pointer.restype = ctypes.c_void_p
    get_pointer.argtypes = [ctypes.py_object, ctypes.c_char_p]
    address = get_pointer(capsule, get_name(capsule))
    support = _MessageTypeSupport.from_address(address)
    digest = support.get_type_hash_func(address).contents
    return f"RIHS{digest.version:02d}_{bytes(digest.value).hex()}"


def _message_class(type_name: str) -> type:
    """``pkg/action/Name_Goal`` -> the Python class, through the action's nested classes."""
    package, kind, name = type_name.split("/")
    base, _, part = name.partition("_")
    cls = getattr(importlib.import_module(f"{package}.{kind}"), base)
    if not part:
        return cls
    parts = part.split("_")
    if parts[0] in ("SendGoal", "GetResult"):
        service = getattr(cls.Impl, f"{parts[0]}Service")
        return getattr(service, parts[1])
    if parts[0] == "FeedbackMessage":
        return cls.Impl.FeedbackMessage
    return getattr(cls, parts[0])


def git_blob_id(data: bytes) -> str:
    """What ``git hash-object`` prints for a file holding ``data``."""
    return hashlib.sha1(b"blob %d\0" % len(data) + data).hexdigest()


@pytest.mark.parametrize("path", sorted(CONTROL_MSGS_BLOBS))
def test_control_msgs_copies_are_byte_identical_to_upstream(path: str) -> None:
    data = (ROOT / "interfaces" / "control_msgs" / path).read_bytes()
    assert git_blob_id(data) == CONTROL_MSGS_BLOBS[path], (
        f"interfaces/control_msgs/{path} differs from upstream at {CONTROL_MSGS_COMMIT}"
    )


@pytest.mark.ros
@pytest.mark.parametrize(
    "type_name",
    sorted(t for t in CONTROL_MSGS_HASHES if "_" in t.split("/")[-1] or "/msg/" in t),
)
def test_built_control_msgs_hash_equals_upstream(type_name: str) -> None:
    assert built_hash(_message_class(type_name)) == expected_hashes()[type_name]


@pytest.mark.parametrize("path", sorted(CONTROL_MSGS_JAZZY_BLOBS))
def test_control_msgs_jazzy_copies_are_byte_identical_to_upstream(path: str) -> None:
    data = (ROOT / "interfaces" / "jazzy" / "control_msgs" / path).read_bytes()
    assert git_blob_id(data) == CONTROL_MSGS_JAZZY_BLOBS[path], (
        f"interfaces/jazzy/control_msgs/{path} differs from upstream at {CONTROL_MSGS_JAZZY_COMMIT}"
    )


@pytest.mark.parametrize("path", sorted(FRANKA_MSGS_BLOBS))
def test_franka_msgs_copies_are_byte_identical_to_upstream(path: str) -> None:
    data = (ROOT / "interfaces" / "franka_msgs" / path).read_bytes()
    assert git_blob_id(data) == FRANKA_MSGS_BLOBS[path], (
        f"interfaces/franka_msgs/{path} differs from upstream at {FRANKA_MSGS_COMMIT}"
    )


@pytest.mark.ros
@pytest.mark.parametrize("type_name", _checked_types(FRANKA_MSGS_HASHES))
def test_built_franka_msgs_hash_equals_upstream(type_name: str) -> None:
    assert built_hash(_message_class(type_name)) == FRANKA_MSGS_HASHES[type_name]


@pytest.mark.ros
@pytest.mark.parametrize(
    "interface",
    [
        "control_msgs/action/GripperCommand",
        "control_msgs/action/ParallelGripperCommand",
        "control_msgs/action/FollowJointTrajectory",
        "franka_msgs/action/ErrorRecovery",
        "franka_msgs/srv/SetFullCollisionBehavior",
    ],
)
def test_installed_action_description_hash_equals_upstream(interface: str) -> None:
    share = Path(sysconfig.get_paths()["data"]) / "share"
    package, kind, name = interface.split("/")
    described = json.loads((share / package / kind / f"{name}.json").read_text())
    hashes = {h["type_name"]: h["hash_string"] for h in described["type_hashes"]}
    assert hashes[interface] == expected_hashes()[interface]


def test_hash_check_can_fail() -> None:
    """A type whose definition differs hashes differently (the check is not vacuous)."""
    from sensor_msgs.msg import JointState

    assert built_hash(JointState) not in CONTROL_MSGS_HASHES.values()
    assert built_hash(JointState) not in FRANKA_MSGS_HASHES.values()
    # the Jazzy and Kilted FollowJointTrajectory really differ: the table is not one value
    assert set(CONTROL_MSGS_JAZZY_HASHES.values()).isdisjoint(CONTROL_MSGS_HASHES.values())
    assert git_blob_id(b"float64 position\n") != CONTROL_MSGS_BLOBS["msg/GripperCommand.msg"]

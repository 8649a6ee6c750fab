r"""Type hashes (RIHS01) of interface files as upstream holds them at one commit, from rosidl.

Why: ``interfaces/`` carries copies of upstream ``control_msgs`` and ``franka_msgs`` files for
venvs built from the PyPI wheels. The copies must hash as a ROS install's package does, or a node
of ours and a ``ros2_control`` controller would not match on the wire. This script computes the
hashes from upstream's own text (``git show COMMIT:PATH`` in a clone), with the same rosidl code
a ROS build runs (``rosidl_adapter`` to IDL, ``rosidl_generator_type_description`` for the
hashes), never from our copies; its output is recorded in ``test/test_interface_hashes.py``,
which compares it with the hashes of the types built into the venv.

Usage (the clone from ``git clone https://github.com/ros-controls/control_msgs``)::

    .venv/bin/python scripts/upstream_type_hashes.py CLONE COMMIT control_msgs \\
        control_msgs/action/GripperCommand.action control_msgs/msg/GripperCommand.msg ...

Dependencies (``sensor_msgs``, ``action_msgs``, ...) are read from the venv's ``share/``.
Prints each type name with its hash on the next line, sorted, then each file's git blob id at
that commit.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path

from rosidl_adapter.action import convert_action_to_idl
from rosidl_adapter.msg import convert_msg_to_idl
from rosidl_adapter.srv import convert_srv_to_idl
from rosidl_generator_type_description import generate_type_hash

CONVERTERS = {
    ".msg": convert_msg_to_idl,
    ".srv": convert_srv_to_idl,
    ".action": convert_action_to_idl,
}


def upstream_hashes(clone: Path, commit: str, package: str, paths: list[str]) -> dict[str, str]:
    """Hash every type defined by ``paths`` (repository paths) at ``commit``.

    Returns:
        ``{type_name: "RIHS01_..."}`` for the files' top-level types and their parts (an
        action's Goal, Result, services, feedback message).
    """
    share = Path(sysconfig.get_paths()["data"]) / "share"
    with tempfile.TemporaryDirectory() as tmp:
        pkg_dir = Path(tmp) / package
        idl_tuples = []
        for path in paths:
            text = subprocess.run(
                ["git", "-C", str(clone), "show", f"{commit}:{path}"],
                check=True,
                capture_output=True,
            ).stdout
            kind = Path(path).suffix
            rel = Path(kind[1:]) / Path(path).name
            (pkg_dir / rel).parent.mkdir(parents=True, exist_ok=True)
            (pkg_dir / rel).write_bytes(text)
            with contextlib.redirect_stdout(io.StringIO()):  # the adapter prints each file
                idl = CONVERTERS[kind](pkg_dir, package, rel, pkg_dir / rel.parent)
            idl_tuples.append(f"{pkg_dir}:{idl.relative_to(pkg_dir)}")
        out = Path(tmp) / "out"
        deps = [f"{d.name}:{d}" for d in share.iterdir() if d.is_dir() and d.name != package]
        args = Path(tmp) / "args.json"
        args.write_text(
            json.dumps(
                {
                    "package_name": package,
                    "output_dir": str(out),
                    "idl_tuples": idl_tuples,
                    "include_paths": deps,
                }
            )
        )
        hashes = {}
        for json_path in generate_type_hash(str(args)):
            top = json.loads(Path(json_path).read_text())["type_hashes"][0]
            hashes[top["type_name"]] = top["hash_string"]
        return hashes


def blob_ids(clone: Path, commit: str, paths: list[str]) -> dict[str, str]:
    """Git blob id of each path at ``commit`` (what ``git hash-object`` gives for a copy)."""
    out = subprocess.run(
        ["git", "-C", str(clone), "ls-tree", commit, *paths],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    return {line.split("\t")[1]: line.split()[2] for line in out.splitlines()}


def main(argv: list[str] | None = None) -> int:
    """Print the hashes and blob ids."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("clone", type=Path)
    parser.add_argument("commit")
    parser.add_argument("package")
    parser.add_argument("paths", nargs="+")
    a = parser.parse_args(argv)
    for name, value in sorted(upstream_hashes(a.clone, a.commit, a.package, a.paths).items()):
        print(f"{name}\n    {value}")
    for path, blob in sorted(blob_ids(a.clone, a.commit, a.paths).items()):
        print(f'    "{path}": "{blob}",')
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""``ext-sense models create`` on hostile places (issue 32): refused before training, never mixed.

- ``--out`` on a read-only file system, or on one with too little room: one line naming the
  place and what is wrong, exit 2, before anything is simulated or trained;
- a bundle whose write fails midway (a full file system) leaves the former bundle as it was and
  nothing beside it;
- a second ``models create`` into a place another one is writing waits for it, then keeps
  what the first made.

The small file systems are real: a tmpfs mounted in a user and mount namespace of the command's
own (``unshare``), so the test needs no privileges and leaves no mount behind.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import textwrap
import threading
from pathlib import Path

import pytest
from sim_models import EXE, write_card

from ext_sense_perception.training.bundle_io import LOCK_FILE, place_lock
from ext_sense_sim import default_models

FOOD_TRIALS = default_models.TRIALS[("food_identification", "nuskin")]
NEEDED_MB = (
    default_models.space_needed(
        (t, default_models.TRIALS[(t, "nuskin")]) for t in default_models.TASKS
    )
    / 2**20
)
"""What ``models create`` asks of a place for the three NUSkin models (about 690 MB)."""


def _in_namespace(place: Path, mount_options: str, command: list[str]) -> list[str]:
    """``command`` run where ``place`` is a fresh tmpfs mounted with ``mount_options``."""
    if shutil.which("unshare") is None:
        pytest.skip("no unshare command here")
    probe = subprocess.run(["unshare", "-rm", "true"], capture_output=True)
    if probe.returncode != 0:
        pytest.skip(f"no user and mount namespaces here: {probe.stderr.decode().strip()}")
    place.mkdir(parents=True, exist_ok=True)
    script = f'mount -t tmpfs -o {mount_options} tmpfs "{place}" && exec "$@"'
    return ["unshare", "-rm", "sh", "-c", script, "sh", *command]


def _create(out: Path, mount_options: str) -> subprocess.CompletedProcess:
    cmd = _in_namespace(out, mount_options, [*EXE, "models", "create", "--out", str(out)])
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize(
    ("mount_options", "message"),
    [
        ("ro,size=1m", "cannot write into {out}: Read-only file system"),
        ("size=5m", f"not enough free space in {{out}}: 5.0 MB free, {NEEDED_MB:.0f} MB needed"),
    ],
    ids=["read_only", "full"],
)
def test_an_unwritable_place_is_refused_before_training(tmp_path, mount_options, message):
    out = tmp_path / "models"
    run = _create(out, mount_options)
    assert run.returncode == 2, run.stderr
    assert run.stderr.splitlines() == [f"ext-sense models: error: {message.format(out=out)}"]
    assert run.stdout == ""  # nothing simulated, trained or announced


def test_current_models_on_a_read_only_place_are_used_as_they_are(tmp_path):
    out = tmp_path / "models"
    bundle = out / "food_identification_nuskin"
    fingerprint = default_models.training_fingerprint(
        "nuskin", "food_fork_nuskin", FOOD_TRIALS, "dataset"
    )
    make = (
        "import sys, pathlib; from sim_models import write_card; "
        "b = write_card(pathlib.Path(sys.argv[1]), 'food_identification', 'nuskin'); "
        f"(b / '{default_models.FINGERPRINT_FILE}').write_text('{fingerprint}\\n')"
    )
    create = [*EXE, "models", "create", "--out", str(out), "--task", "food_identification"]
    test_dir = str(Path(__file__).parent)
    script = (
        f'PYTHONPATH="{test_dir}" "{sys.executable}" -c "{make}" "{bundle}" '
        f'&& mount -o remount,ro "{out}" && exec "$@"'
    )
    cmd = _in_namespace(out, "size=1m", ["sh", "-c", script, "sh", *create])
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert f"[models] using model {bundle} (trained from the same inputs)" in run.stderr


def test_a_failed_bundle_write_leaves_the_former_bundle_and_nothing_else(tmp_path):
    place = tmp_path / "place"
    code = textwrap.dedent(
        f"""
        import json, pathlib
        from ext_sense_perception.errors import PerceptionError
        from ext_sense_perception.training.bundle_io import staged_bundle
        target = pathlib.Path("{place}") / "food_identification_nuskin"
        target.mkdir()
        (target / "model_card.json").write_text("former")
        try:
            with staged_bundle(target) as staged:
                (staged / "model_card.json").write_text("new")
                (staged / "model.joblib").write_bytes(bytes(2 * 2**20))  # over the 1 MB
            error = None
        except PerceptionError as err:
            error = str(err)
        print(json.dumps({{
            "error": error,
            "card": (target / "model_card.json").read_text(),
            "files": sorted(p.name for p in target.parent.iterdir()),
            "bundle": sorted(p.name for p in target.iterdir()),
        }}))
        """
    )
    cmd = _in_namespace(place, "size=1m", [sys.executable, "-c", code])
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    seen = json.loads(run.stdout)
    target = place / "food_identification_nuskin"
    assert seen == {
        "error": f"cannot write the bundle {target}: No space left on device",
        "card": "former",
        "files": ["food_identification_nuskin"],
        "bundle": ["model_card.json"],
    }


def test_a_second_create_into_the_same_place_waits_then_keeps_the_first_ones_model(tmp_path):
    out = tmp_path / "models"
    bundle = out / "food_identification_nuskin"
    out.mkdir()
    with place_lock(out):  # the first create, still training
        second = subprocess.Popen(
            [*EXE, "models", "create", "--out", str(out), "--task", "food_identification"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        assert second.stderr is not None
        first_line = second.stderr.readline()
        assert first_line == f"[models] waiting: another process is writing models into {out}\n"
        done = threading.Event()
        threading.Thread(target=lambda: (second.wait(), done.set()), daemon=True).start()
        assert not done.wait(1.0), "the second create did not wait for the lock"
        # the first create's bundle, complete before it lets go of the place
        write_card(bundle, "food_identification", "nuskin")
        fingerprint = default_models.training_fingerprint(
            "nuskin", "food_fork_nuskin", FOOD_TRIALS, "dataset"
        )
        (bundle / default_models.FINGERPRINT_FILE).write_text(fingerprint + "\n")
        card = (bundle / "model_card.json").read_text()
    out_text, err_text = second.communicate(timeout=120)
    assert second.returncode == 0, err_text
    assert f"using model {bundle} (trained from the same inputs)" in err_text
    assert "simulated" not in err_text  # nothing trained a second time
    assert (bundle / "model_card.json").read_text() == card
    assert sorted(p.name for p in out.iterdir()) == [LOCK_FILE, bundle.name]
    assert str(out) in out_text

"""Where model bundles are found: by name along a fixed search path, or by path (no ROS).

A path is absolute, holds a ``/`` or starts with ``.`` or ``~``; a name (empty: the task's
default ``<task>_<sensor>``) is looked up, first hit wins, never in the working directory, in
``$EXT_SENSE_MODELS``, the user's data directory (``$XDG_DATA_HOME/ext_sense/models``, where
``ext-sense models create`` writes), the installed package share, and a source checkout's
``build/models``.
"""

from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path
from typing import NamedTuple

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.model_card import CARD_FILE
from ext_sense_runtime.enums import Sensor, Task

ENV_VAR = "EXT_SENSE_MODELS"
PACKAGE = "ext_sense_perception"
CREATE_COMMAND = "ext-sense models create"
"""The command that creates the default models (``--sensor biotac`` for the BioTac ones)."""


class ModelNotFoundError(PerceptionError):
    """No model bundle under that name or path."""


class SearchPlace(NamedTuple):
    """One place of the search path (``root`` None when it does not apply)."""

    label: str
    root: Path | None


def default_name(task: str, sensor: str) -> str:
    """A task's default model name, ``<task>_<sensor>`` (a PerceptionError for an unknown one)."""
    task_label = Task.parse(task, PerceptionError).label
    return f"{task_label}_{Sensor.parse(sensor, PerceptionError).label}"


def create_command(sensor: str) -> str:
    """The command that creates the default models for ``sensor``."""
    if sensor == Sensor.NUSKIN.label:
        return CREATE_COMMAND
    return f"{CREATE_COMMAND} --sensor {sensor}"


def create_hint(sensor: str) -> str:
    """How to create the default models, where that writes them, and the colcon form."""
    command = create_command(sensor)
    return (
        f"create the default models with '{command}' (it writes {default_store()}; in a colcon "
        f"workspace: 'ros2 run ext_sense {command}')"
    )


def user_models_dir() -> Path:
    """``$XDG_DATA_HOME/ext_sense/models`` (``~/.local/share`` when unset or relative, per XDG)."""
    xdg = os.environ.get("XDG_DATA_HOME", "")
    base = Path(xdg) if xdg and Path(xdg).is_absolute() else Path.home() / ".local" / "share"
    return base / "ext_sense" / "models"


def default_store() -> Path:
    """Where new models are written: ``$EXT_SENSE_MODELS`` when set, else the user's data."""
    env = os.environ.get(ENV_VAR, "")
    return Path(env).expanduser() if env else user_models_dir()


def share_models_dirs() -> list[Path]:
    """The installed package share's ``models`` directories: ament index, then ``sys.prefix``."""
    found: list[Path] = []
    try:
        from ament_index_python.packages import get_package_share_directory
    except ImportError:  # not a ROS environment: sys.prefix only
        pass
    else:
        # not in the index: no AMENT_PREFIX_PATH (OSError), or not installed (a KeyError)
        with contextlib.suppress(LookupError, ValueError, OSError):
            found.append(Path(get_package_share_directory(PACKAGE)) / "models")
    prefix = Path(sys.prefix) / "share" / PACKAGE / "models"
    if prefix not in found:
        found.append(prefix)
    return found


def checkout_root(start: Path | None = None) -> Path | None:
    """The source checkout this package runs from (editable or colcon-installed in it)."""
    here = (start or Path(__file__)).resolve()
    for parent in here.parents:
        if (parent / "pyproject.toml").is_file() and (
            parent / "src" / PACKAGE / "package.xml"
        ).is_file():
            return parent
    return None


def search_places() -> list[SearchPlace]:
    """Every place a name is looked up in, in order."""
    env = os.environ.get(ENV_VAR, "")
    places = [
        SearchPlace(f"${ENV_VAR}", Path(env).expanduser() if env else None),
        SearchPlace("user data", user_models_dir()),
    ]
    places += [SearchPlace("package share", d) for d in share_models_dirs()]
    root = checkout_root()
    places.append(SearchPlace("checkout", root / "build" / "models" if root else None))
    return places


def is_path(name_or_path: str | Path) -> bool:
    """Whether a model is given by path rather than named (a bare name never means ``./name``)."""
    if isinstance(name_or_path, Path):
        return True
    text = str(name_or_path)
    return (
        os.path.isabs(text)
        or os.sep in text
        or (os.altsep is not None and os.altsep in text)
        or text.startswith((".", "~"))
    )


def is_bundle(path: Path) -> bool:
    """Whether ``path`` is a bundle directory (holds a model card)."""
    return (path / CARD_FILE).is_file()


def describe(place: SearchPlace) -> str:
    """A place as the error and ``ext-sense models list`` name it."""
    if place.root is None:
        why = "unset" if place.label.startswith("$") else "not running from a source checkout"
        return f"{place.label} ({why})"
    return f"{place.label} {place.root}"


def find_model(name_or_path: str | Path, task: str, sensor: str) -> Path:
    """The bundle directory of a model named or given by path (``""``: the task's default).

    ModelNotFoundError: no bundle there (for a name, the one-line message lists every place searched
    and the command that creates the default models). PerceptionError: an unknown task or sensor.
    """
    hint = create_hint(sensor)
    if is_path(name_or_path) and str(name_or_path):
        path = Path(name_or_path).expanduser()
        if is_bundle(path):
            return path.absolute()
        raise ModelNotFoundError(
            f"No model bundle at {str(path)!r} (no {CARD_FILE} there). To fix: {hint}, or "
            "give another bundle directory."
        )
    name = str(name_or_path) or default_name(task, sensor)
    places = search_places()
    for place in places:
        if place.root is not None and is_bundle(place.root / name):
            return (place.root / name).absolute()
    searched = "; ".join(describe(p) for p in places)
    raise ModelNotFoundError(
        f"No model {name!r} for {task}/{sensor}: searched {searched}. "
        f"To fix: {hint}, or give a bundle directory."
    )


def locate_model(name_or_path: str | Path, task: str, sensor: str) -> Path:
    """As :func:`find_model`, but a path is returned unchecked (the nodes retry it and say why)."""
    if str(name_or_path) and is_path(name_or_path):
        return Path(name_or_path).expanduser()
    return find_model(name_or_path, task, sensor)


class StoredModel(NamedTuple):
    """A bundle found in one place of the search path (``shadowed``: an earlier one wins)."""

    place: SearchPlace
    name: str
    path: Path
    shadowed: bool


def stored_models() -> list[StoredModel]:
    """Every bundle in every place of the search path, in search order."""
    out: list[StoredModel] = []
    seen: set[str] = set()
    for place in search_places():
        if place.root is None or not place.root.is_dir():
            continue
        for path in sorted(p for p in place.root.iterdir() if p.is_dir() and is_bundle(p)):
            out.append(StoredModel(place, path.name, path, path.name in seen))
        seen.update(m.name for m in out)
    return out

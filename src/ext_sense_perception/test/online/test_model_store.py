"""The model search path: env, user data, package share, checkout; never the working directory."""

from __future__ import annotations

from pathlib import Path

import pytest

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online import model_store
from ext_sense_perception.online.model_store import (
    ModelNotFoundError,
    checkout_root,
    default_name,
    default_store,
    find_model,
    is_path,
    locate_model,
    search_places,
    stored_models,
    user_models_dir,
)

NAME = "tap_localization_nuskin"


def _bundle(root: Path, name: str = NAME) -> Path:
    path = root / name
    path.mkdir(parents=True)
    (path / "model_card.json").write_text("{}")
    return path


@pytest.fixture
def places(tmp_path, monkeypatch):
    """Four empty places (env, user data, share, checkout) and a working directory."""
    dirs = {k: tmp_path / k for k in ("env", "xdg", "share", "checkout", "cwd")}
    for d in dirs.values():
        d.mkdir()
    monkeypatch.setenv("EXT_SENSE_MODELS", str(dirs["env"]))
    monkeypatch.setenv("XDG_DATA_HOME", str(dirs["xdg"]))
    monkeypatch.setattr(model_store, "share_models_dirs", lambda: [dirs["share"]])
    monkeypatch.setattr(model_store, "checkout_root", lambda: dirs["checkout"])
    monkeypatch.chdir(dirs["cwd"])
    dirs["user"] = dirs["xdg"] / "ext_sense" / "models"
    dirs["build"] = dirs["checkout"] / "build" / "models"
    return dirs


def test_search_order_env_user_share_checkout(places):
    labels = [(p.label, p.root) for p in search_places()]
    assert labels == [
        ("$EXT_SENSE_MODELS", places["env"]),
        ("user data", places["user"]),
        ("package share", places["share"]),
        ("checkout", places["build"]),
    ]
    for key in ("build", "share", "user", "env"):  # each place shadows the ones after it
        _bundle(places[key])
        assert find_model("", "tap_localization", "nuskin") == places[key] / NAME
    found = stored_models()
    assert [m.place.label for m in found] == [
        "$EXT_SENSE_MODELS",
        "user data",
        "package share",
        "checkout",
    ]
    assert [m.shadowed for m in found] == [False, True, True, True]


def test_never_the_working_directory(places):
    _bundle(places["cwd"])
    _bundle(places["cwd"] / "build" / "models")
    with pytest.raises(ModelNotFoundError):
        find_model("", "tap_localization", "nuskin")
    with pytest.raises(ModelNotFoundError):
        find_model(NAME, "tap_localization", "nuskin")
    # the working directory only by an explicit path
    assert find_model(f"./{NAME}", "tap_localization", "nuskin") == places["cwd"] / NAME


def test_missing_model_names_every_place_and_the_command(places, monkeypatch):
    monkeypatch.delenv("EXT_SENSE_MODELS")
    with pytest.raises(ModelNotFoundError) as info:
        find_model("", "handover", "nuskin")
    msg = str(info.value)
    assert "\n" not in msg
    assert "'handover_stability_nuskin'" in msg
    assert "$EXT_SENSE_MODELS (unset)" in msg
    for key in ("user", "share", "build"):
        assert str(places[key]) in msg
    assert "'ext-sense models create'" in msg
    assert "ros2 run ext_sense ext-sense models create" in msg
    assert f"it writes {places['user']}" in msg
    with pytest.raises(ModelNotFoundError, match="models create --sensor biotac"):
        find_model("", "food", "biotac")


def test_paths_and_names():
    for path in ("/abs/model", "rel/model", "./m", "~/m"):
        assert is_path(path)
    assert is_path(Path("m"))
    assert not is_path("tap_localization_nuskin")
    assert default_name("tap", "NUSkin") == NAME
    with pytest.raises(PerceptionError, match="'task' parameter"):
        default_name("juggling", "nuskin")


def test_a_given_path_is_checked_by_find_and_not_by_locate(places, tmp_path):
    missing = tmp_path / "nowhere" / "model"
    with pytest.raises(ModelNotFoundError, match=r"No model bundle at .*model_card\.json"):
        find_model(missing, "tap_localization", "nuskin")
    assert locate_model(str(missing), "tap_localization", "nuskin") == missing
    bundle = _bundle(tmp_path / "elsewhere")
    assert find_model(str(bundle), "tap_localization", "nuskin") == bundle
    with pytest.raises(ModelNotFoundError):  # a name is still looked up by locate
        locate_model("no_such_model", "tap_localization", "nuskin")


def test_user_data_dir_follows_xdg(monkeypatch, tmp_path):
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.delenv("XDG_DATA_HOME", raising=False)
    assert user_models_dir() == tmp_path / "home" / ".local" / "share" / "ext_sense" / "models"
    monkeypatch.setenv("XDG_DATA_HOME", "relative/ignored")  # the spec ignores relative paths
    assert user_models_dir() == tmp_path / "home" / ".local" / "share" / "ext_sense" / "models"
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))
    assert user_models_dir() == tmp_path / "data" / "ext_sense" / "models"
    monkeypatch.delenv("EXT_SENSE_MODELS", raising=False)
    assert default_store() == user_models_dir()
    monkeypatch.setenv("EXT_SENSE_MODELS", str(tmp_path / "env"))
    assert default_store() == tmp_path / "env"


def test_checkout_root_from_source_and_from_a_colcon_install(tmp_path):
    root = tmp_path / "repo"
    (root / "src" / "ext_sense_perception").mkdir(parents=True)
    (root / "src" / "ext_sense_perception" / "package.xml").write_text("<package/>")
    (root / "pyproject.toml").write_text("")
    (root / "ros2_ws").mkdir()
    (root / "ros2_ws" / "src").symlink_to("../src")
    source = root / "src" / "ext_sense_perception" / "ext_sense_perception" / "online" / "m.py"
    installed = (
        root
        / "ros2_ws/install/ext_sense_perception/lib/python3.12/site-packages"
        / "ext_sense_perception/online/m.py"
    )
    for f in (source, installed):
        f.parent.mkdir(parents=True)
        f.write_text("")
        assert checkout_root(f) == root.resolve()
    assert checkout_root(tmp_path / "site-packages" / "m.py") is None
    # this module itself runs from the project's checkout in the test environment
    assert (checkout_root() / "src" / "ext_sense_perception").is_dir()

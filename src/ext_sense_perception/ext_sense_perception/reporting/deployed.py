"""The deployed models behind the report's latency columns, as cached fits a cluster can run.

A latency is that of the model the protocol would deploy, trained on every window with the
modal hyper-parameters. Such fits take as long as a split's (about 10 minutes per tap data set
run in turn), so they run and are cached where the split fits run; only their timing runs in
the report's process, never beside a fit. No ROS.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any, NamedTuple

from ext_sense_perception.data.window_set import WindowSet
from ext_sense_perception.training import fit as fit_module
from ext_sense_perception.training.fit import TrainedModel, fit_model
from ext_sense_perception.training.models import make_pipeline
from ext_sense_perception.training.protocol import features_for
from ext_sense_perception.training.split_fit import code_digest, code_text

DEPLOYED_STORE = "deployed"
"""The fit cache's subdirectory of deployed models: up to tens of MB each, so kept apart from
the 1-2 kB split results (``docs/perception_report/fits`` is in git, these are ignored).
"""


class DeployedTask(NamedTuple):
    """One deployed model's fit: :func:`~ext_sense_perception.training.fit.fit_model`'s arguments.

    All but the window set, which the executor sends to the workers once.
    """

    features: str
    model: str
    feature_params: dict[str, Any]
    grid: dict[str, list[Any]]  # one value per parameter: the splits' modal choice
    seed: int
    n_jobs: int
    model_params: dict[str, Any] | None


def fit_deployed(task: DeployedTask, ws: WindowSet) -> TrainedModel:
    """Train the deployed model of ``task`` on every window of ``ws`` (a worker's job)."""
    return fit_model(
        ws,
        task.features,
        task.model,
        task.feature_params,
        task.grid,
        seed=task.seed,
        n_jobs=task.n_jobs,
        model_params=task.model_params,
    )


def deployed_key(task: DeployedTask, ws: WindowSet, data: str) -> str:
    """The cache key of a deployed fit: its configuration, the data's hash and its code's.

    The code is the pipeline's (:func:`~.split_fit.code_digest`) plus the fitting module's and this
    one's, so a change to one model retrains only its deployed models.
    """
    feats = features_for(ws, task.features, **task.feature_params)
    pipe, _ = make_pipeline(feats, task.model, ws.is_regression, task.seed)
    config = repr(
        (
            "deployed",
            task.features,
            task.model,
            sorted(task.feature_params.items()),
            sorted(task.grid.items()),
            task.seed,
            sorted((task.model_params or {}).items()),
        )
    )
    h = hashlib.blake2b(digest_size=16)
    h.update(config.encode())
    h.update(data.encode())
    h.update(code_digest(pipe).encode())
    h.update(code_text(Path(fit_module.__file__)))
    h.update(code_text(Path(__file__)))
    return h.hexdigest()

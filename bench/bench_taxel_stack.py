"""Taxel-wise stacked SVR against the default FFT + SVR (RBF): training time and latency.

Both trained on the same windows: training seconds, support vectors, bundle sizes, and one
window through the saved bundle (p50/p99, ONNX Runtime and scikit-learn, the two models'
windows interleaved so load hits both alike; target ONNX p99 <= 2 ms).

    python bench/bench_taxel_stack.py                      # 1000 synthetic taps
    python bench/bench_taxel_stack.py --quick              # 100 synthetic taps, about 10 s
    python bench/bench_taxel_stack.py --data DATASET.npz   # simulator dataset (real SV counts)
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

# a sibling script: ``python bench/bench_taxel_stack.py`` puts bench/ first on sys.path
from common import pct, synthetic_taps

from ext_sense_perception.data.sources import from_sim_dataset
from ext_sense_perception.online.model_card import ONNX_FILE, SKLEARN_FILE
from ext_sense_perception.online.predictor import load_model
from ext_sense_perception.training.bundle_io import save_bundle
from ext_sense_perception.training.fit import TrainedModel, fit_model

MODELS = ("svm_rbf", "taxel_svr")


def support_vectors(trained: TrainedModel) -> int:
    """Support vectors summed over the model's SVRs."""
    model = trained.pipeline.steps[-1][1]
    if hasattr(model, "svrs_"):
        return sum(len(s.support_) for s in model.svrs_)
    return len(model.support_)


def main() -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--quick", action="store_true", help="100 synthetic taps, fewer repeats")
    ap.add_argument("--data", default=None, help="a simulator tap dataset.npz (default synthetic)")
    ap.add_argument("--repeat", type=int, default=None, help="windows timed per model")
    args = ap.parse_args()
    ws = from_sim_dataset(args.data) if args.data else synthetic_taps(100 if args.quick else 1000)
    repeat = args.repeat or (100 if args.quick else 1000)
    print(f"{len(ws.y)} taps, windows {ws.X.shape[1:]} ({ws.source})")
    loaded = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in MODELS:
            t0 = time.perf_counter()
            trained = fit_model(ws, "fft", name)
            train_s = time.perf_counter() - t0
            out = save_bundle(trained, Path(tmp) / name)
            loaded[name] = {b: load_model(out, b) for b in ("onnx", "sklearn")}
            mae = trained.card.metrics["cv_mae_m"] * 100
            mb = {f: (out / f).stat().st_size / 1e6 for f in (ONNX_FILE, SKLEARN_FILE)}
            print(
                f"{name:10s} train {train_s:6.1f} s, CV MAE {mae:.2f} cm, "
                f"{support_vectors(trained)} support vectors, "
                f"{mb[ONNX_FILE]:.1f} MB ONNX, {mb[SKLEARN_FILE]:.1f} MB joblib"
            )
        windows = [ws.X[i % len(ws.X)] for i in range(repeat)]
        for backend in ("onnx", "sklearn"):
            times: dict[str, list[float]] = {m: [] for m in MODELS}
            for m in MODELS:
                loaded[m][backend].predict(windows[0])
            n = repeat if backend == "onnx" else max(repeat // 5, 20)
            for w in windows[:n]:
                for m in MODELS:
                    t0 = time.perf_counter_ns()
                    loaded[m][backend].predict(w)
                    times[m].append((time.perf_counter_ns() - t0) / 1e6)
            p = {m: pct(times[m]) for m in MODELS}
            for m in MODELS:
                target = " (target p99 <= 2 ms)" if backend == "onnx" else ""
                print(
                    f"{m:10s} {backend:7s} one window p50 / p99: "
                    f"{p[m][0]:.3f} / {p[m][1]:.3f} ms{target}"
                )
            print(
                f"taxel_svr / svm_rbf {backend}: p50 x{p['taxel_svr'][0] / p['svm_rbf'][0]:.1f}, "
                f"p99 x{p['taxel_svr'][1] / p['svm_rbf'][1]:.1f}"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

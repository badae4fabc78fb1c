"""Smoke test of the benchmark script: ``benchmarks/run.py --quick`` runs and writes its JSON."""
from __future__ import annotations

import json
import math
import runpy
from pathlib import Path

RUN_PY = Path(__file__).resolve().parents[1] / "benchmarks" / "run.py"

KEYS = (
    "kf_samples_per_s",
    "fusion_samples_per_s",
    "madgwick_samples_per_s",
    "danae_train_steps_per_s",
    "danae_infer_ms_per_sample",
)


def test_quick_benchmark_writes_json(tmp_path: Path, capsys) -> None:
    main = runpy.run_path(str(RUN_PY), run_name="danae_benchmarks")["main"]
    out = tmp_path / "bench" / "benchmarks.json"
    returned = main(["--quick", "--path", "native", "--json", str(out)])
    data = json.loads(out.read_text(encoding="utf-8"))
    assert data == returned
    for key in KEYS:
        value = data[key]
        assert isinstance(value, (int, float)) and not isinstance(value, bool), (key, value)
        assert math.isfinite(value) and value > 0, (key, value)
    assert isinstance(data["device"], str) and data["device"]
    machine = data["machine"]
    for key in ("python", "torch", "cpu_count", "cpu_model"):
        assert machine[key], key
    printed = capsys.readouterr().out
    assert "total wall time" in printed and "KF target" in printed
    isa = machine["isa"]
    assert isa["torch_capability"] in printed and list(data["paths"]) == [
        "AVX2 (forced)" if isa["avx2_forced"] else f"{isa['torch_capability']} (native)"]


def test_the_avx2_path_runs_in_a_child_process_with_avx2_kernels() -> None:
    """The forced path must really be AVX2 in the child (torch reads the variables at import)."""
    ns = runpy.run_path(str(RUN_PY), run_name="danae_benchmarks")
    child = ns["run_avx2_path"](["--quick"])
    isa = child["machine"]["isa"]
    assert isa["avx2_forced"] and isa["torch_capability"] in ("AVX2", "DEFAULT"), isa
    assert child["paper_epoch_50k_s"] > 0 and math.isfinite(child["predict_100k_s"])

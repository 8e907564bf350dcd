"""Check an exported DeepFoids policy with the ONNX tools people use.

Reads target/onnx-check/ (written by `cargo test -p deepfoids-onnx`):
policy.onnx, obs_0.bin, obs_1.bin, expected.bin (little-endian float32), case.json —
the PPO actor there, the SAC actor in sac/.
Checks: onnx.checker.check_model(full_check=True); the input and output names,
the dynamic batch axis and the constants of Unity ML-Agents' interface; and
onnxruntime's deterministic actions against the Burn actor's (max abs diff <= 1e-4).
"""
import json
import sys
from pathlib import Path

import numpy as np
import onnx
import onnxruntime as ort


def check(folder: Path) -> None:
    path = folder / "policy.onnx"
    model = onnx.load(str(path))
    onnx.checker.check_model(model, full_check=True)

    graph = model.graph
    inputs = {i.name: [d.dim_param or d.dim_value for d in i.type.tensor_type.shape.dim] for i in graph.input}
    outputs = [o.name for o in graph.output]
    assert inputs == {"obs_0": ["batch", 18, 20, 34], "obs_1": ["batch", 6]}, inputs
    assert outputs == [
        "version_number",
        "memory_size",
        "continuous_actions",
        "continuous_action_output_shape",
        "deterministic_continuous_actions",
    ], outputs
    opset = [o.version for o in model.opset_import if o.domain in ("", "ai.onnx")]
    meta = {p.key: p.value for p in model.metadata_props}
    for key in ("species", "scene", "algorithm", "training_step", "observation_layout"):
        assert key in meta, f"metadata lacks {key}"

    batch = json.loads((folder / "case.json").read_text())["batch"]
    obs_0 = np.fromfile(folder / "obs_0.bin", dtype="<f4").reshape(batch, 18, 20, 34)
    obs_1 = np.fromfile(folder / "obs_1.bin", dtype="<f4").reshape(batch, 6)
    expected = np.fromfile(folder / "expected.bin", dtype="<f4").reshape(batch, 3)

    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    result = dict(zip(outputs, session.run(outputs, {"obs_0": obs_0, "obs_1": obs_1})))
    assert result["version_number"].tolist() == [3.0], result["version_number"]
    assert result["memory_size"].tolist() == [0.0]
    assert result["continuous_action_output_shape"].tolist() == [3.0]
    det = result["deterministic_continuous_actions"]
    diff = float(np.abs(det - expected).max())
    assert diff <= 1e-4, f"onnxruntime vs Burn: max abs difference {diff}"
    sampled = result["continuous_actions"]
    assert sampled.shape == (batch, 3) and np.all(np.abs(sampled) <= 1.0)
    one = session.run(["deterministic_continuous_actions"], {"obs_0": obs_0[:1], "obs_1": obs_1[:1]})[0]
    assert float(np.abs(one - expected[:1]).max()) <= 1e-4
    print(
        f"onnx check ok ({meta['algorithm']}): opset {opset}, IR {model.ir_version}, {path.stat().st_size} bytes; "
        f"onnxruntime {ort.__version__} vs Burn max abs diff {diff:.2e} on {batch} observations"
    )


root = Path(sys.argv[1] if len(sys.argv) > 1 else "target/onnx-check")
cases = [root] + sorted(d for d in root.iterdir() if (d / "policy.onnx").is_file())
for case in cases:
    check(case)

"""The baseline of the inference benchmark: the same ONNX model on the same
preprocessed crops with Python onnxruntime, as a user would run it.

    python bench_onnxruntime.py MODEL INPUTS.npy REPEAT THREADS

Prints JSON: per-call times (ns) and the outputs of the first crops (for the
Rust/Python agreement check)."""

import json
import sys
import time

import numpy as np
import onnxruntime as ort


def main():
    model, inputs, repeat, threads = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
    so = ort.SessionOptions()
    so.intra_op_num_threads = threads
    so.inter_op_num_threads = 1
    sess = ort.InferenceSession(model, so, providers=["CPUExecutionProvider"])
    x = np.load(inputs).astype(np.float32)
    crops = [np.ascontiguousarray(c[None, None]) for c in x]
    for c in crops[:20]:
        sess.run(["joints"], {"depth": c})
    times = []
    for _ in range(repeat):
        for c in crops:
            t0 = time.perf_counter_ns()
            sess.run(["joints"], {"depth": c})
            times.append(time.perf_counter_ns() - t0)
    outputs = [sess.run(["joints"], {"depth": c})[0][0].tolist() for c in crops[:10]]
    print(json.dumps({"onnxruntime": ort.__version__, "times_ns": times, "outputs": outputs}))


if __name__ == "__main__":
    main()

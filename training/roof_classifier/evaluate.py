"""Evaluates an exported roof model on a rendered set the way citymesh runs it: ONNX Runtime,
and the probabilities averaged over the 8 turns and flips of each crop (citymesh's
OnnxClassifier does the same). Prints accuracy and the confusion matrix, overall and by whether
the footprint mask was given; writes them to a JSON file for the model card.

    .venv-train/bin/python training/roof_classifier/evaluate.py MODEL.onnx SET_DIR OUT.json
"""

import json
import sys

import numpy as np
import onnxruntime as ort

from train import CLASSES, load


def dihedral(x):
    """The 8 turns and flips of N x C x H x W crops, in citymesh's order."""
    out = []
    for flip in (False, True):
        y = x[:, :, :, ::-1] if flip else x
        for k in range(4):
            out.append(np.rot90(y, k, axes=(2, 3)))
    return out


def predict(sess, x, batch=256):
    probs = []
    for i in range(0, len(x), batch):
        xb = x[i:i + batch].astype(np.float32) / 255.0
        p = np.mean([sess.run(None, {"crops": np.ascontiguousarray(v)})[0] for v in dihedral(xb)], axis=0)
        probs.append(p)
    return np.concatenate(probs)


def report(y, p):
    confusion = np.zeros((3, 3), dtype=np.int64)
    for t, q in zip(y, p.argmax(1)):
        confusion[t, q] += 1
    return {"count": int(len(y)), "accuracy": float(np.trace(confusion) / max(len(y), 1)),
            "confusion": confusion.tolist()}


def main():
    model, folder, out = sys.argv[1:4]
    sess = ort.InferenceSession(model, providers=["CPUExecutionProvider"])
    x, y = load(folder)
    p = predict(sess, x)
    known = x[:, 3, 0, 0] != 128
    result = {"classes": CLASSES, "all": report(y, p), "with mask": report(y[known], p[known]),
              "without mask": report(y[~known], p[~known])}
    print(json.dumps(result, indent=2))
    json.dump(result, open(out, "w"), indent=2)


if __name__ == "__main__":
    main()

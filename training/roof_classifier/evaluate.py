"""Evaluates an exported roof model on a rendered set: ONNX Runtime, and the probabilities
averaged over the 8 turns and flips of each crop; with `rect shift`, the way citymesh's
OnnxClassifier runs it. Prints accuracy and the confusion matrix, overall and by whether
the footprint mask was given; writes them to a JSON file for the model card.

    .venv-train/bin/python training/roof_classifier/evaluate.py MODEL.onnx SET_DIR OUT.json [rect] [shift]

With `rect`, crops with a known footprint are averaged over the 4 turns and flips of a rectangle
only (for a model trained with `train.py --symmetry rect`); crops without one over all 8.
With `shift`, each turn is also run with the crop shifted by 2 px each way (wrapping around),
as citymesh does (`SHIFTS` in src/roofs/classifier/onnx.rs).
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


# The shifts (rows, columns) citymesh runs each turn at.
SHIFTS = [(0, 0), (2, 0), (-2, 0), (0, 2), (0, -2)]


def predict(sess, x, batch=256, rect=False, shifts=((0, 0),)):
    """Class probabilities of crops, averaged over their turns and flips at each of `shifts`."""
    return np.mean([predict_turns(sess, np.roll(x, s, axis=(2, 3)), batch, rect) for s in shifts], axis=0)


def predict_turns(sess, x, batch, rect):
    probs = []
    for i in range(0, len(x), batch):
        xb = x[i:i + batch].astype(np.float32) / 255.0
        runs = [sess.run(None, {"crops": np.ascontiguousarray(v)})[0] for v in dihedral(xb)]
        p = np.mean(runs, axis=0)
        if rect:
            # dihedral() order: k = 0..3 unflipped, then k = 0..3 flipped; even k keep the
            # long side horizontal.
            known = xb[:, 3, 0, 0] != 128 / 255
            p_rect = np.mean([runs[j] for j in (0, 2, 4, 6)], axis=0)
            p = np.where(known[:, None], p_rect, p)
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
    options = set(sys.argv[4:])
    if options - {"rect", "shift"}:
        sys.exit(__doc__)
    sess = ort.InferenceSession(model, providers=["CPUExecutionProvider"])
    x, y = load(folder)
    p = predict(sess, x, rect="rect" in options, shifts=SHIFTS if "shift" in options else ((0, 0),))
    known = x[:, 3, 0, 0] != 128
    result = {"classes": CLASSES, "all": report(y, p), "with mask": report(y[known], p[known]),
              "without mask": report(y[~known], p[~known])}
    print(json.dumps(result, indent=2))
    json.dump(result, open(out, "w"), indent=2)


if __name__ == "__main__":
    main()

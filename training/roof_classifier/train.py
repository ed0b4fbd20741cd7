"""Trains citymesh's roof classifier (flat / gabled / hipped) on crops rendered by
`citymesh render-roofs`, evaluates it on a held-out set rendered with another seed and palette,
and exports ONNX. See README.md in this folder for the whole, reproducible command sequence.

Input of the network: N x 4 x 64 x 64 floats: R, G, B as sRGB / 255 and the footprint mask
(1 inside, 0 outside, 128/255 everywhere when unknown). Output: N x 3 class probabilities.
"""

import argparse
import csv
import json
import os
import time

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F
from PIL import Image

CLASSES = ["flat", "gabled", "hipped"]
SIZE = 64
# The mask value of a crop whose footprint is not known (as citymesh feeds it: 128 / 255).
UNKNOWN = 128 / 255


def load(folder):
    """Images (uint8, N x 4 x S x S; mask 128 where unknown) and labels of a rendered set."""
    cache = os.path.join(folder, "crops.npz")
    if os.path.exists(cache) and os.path.getmtime(cache) >= os.path.getmtime(os.path.join(folder, "labels.csv")):
        z = np.load(cache)
        return z["x"], z["y"]
    rows = list(csv.DictReader(open(os.path.join(folder, "labels.csv"))))
    x = None
    y = np.empty(len(rows), dtype=np.int64)
    for i, r in enumerate(rows):
        im = Image.open(os.path.join(folder, r["file"]))
        a = np.asarray(im)
        if x is None:
            x = np.empty((len(rows), 4, a.shape[0], a.shape[1]), dtype=np.uint8)
        x[i, :3] = a[:, :, :3].transpose(2, 0, 1)
        x[i, 3] = a[:, :, 3] if a.shape[2] == 4 else 128
        y[i] = CLASSES.index(r["class"])
    np.savez(cache, x=x, y=y)
    return x, y


class Residual(nn.Module):
    """x + a 3x3 convolution of x. Its batch norm starts at zero, so a block added to a trained
    net starts as the identity and the net answers as before (`train.py --init`)."""

    def __init__(self, c):
        super().__init__()
        self.body = nn.Sequential(nn.Conv2d(c, c, 3, padding=1, bias=False), nn.BatchNorm2d(c))
        nn.init.zeros_(self.body[1].weight)

    def forward(self, x):
        return torch.relu(x + self.body(x))


class RoofNet(nn.Module):
    """A small VGG-style CNN with batch norm and global average pooling."""

    def __init__(self, width=(16, 32, 64, 128), spatial=False, deep=False, residual=0):
        super().__init__()
        c1, c2, c3, c4 = width

        def block(i, o):
            return [nn.Conv2d(i, o, 3, padding=1, bias=False), nn.BatchNorm2d(o), nn.ReLU(inplace=True)]

        self.features = nn.Sequential(
            *block(4, c1), nn.MaxPool2d(2),                    # 32
            *block(c1, c2), *block(c2, c2), nn.MaxPool2d(2),   # 16
            *block(c2, c3), *block(c3, c3), nn.MaxPool2d(2),   # 8
            *block(c3, c4),
            # With `deep`, a second layer at 8 x 8 widens what each feature sees to most of the roof.
            *(block(c4, c4) if deep else []),
            # With `residual`, that many residual blocks at 8 x 8 more.
            *(Residual(c4) for _ in range(residual)),
        )
        # With `spatial`, the head also sees the features averaged over each quarter of the
        # crop: crops are aligned (long side horizontal), so where a feature lies says something.
        self.spatial = spatial
        self.head = nn.Sequential(nn.Dropout(0.3), nn.Linear(c4 * (5 if spatial else 1), 3))
        self.register_buffer("mean", torch.tensor([0.45, 0.45, 0.45, 0.5]).view(1, 4, 1, 1))
        self.register_buffer("scale", torch.tensor([0.25, 0.25, 0.25, 0.5]).view(1, 4, 1, 1))

    def forward(self, x):
        x = (x - self.mean) / self.scale
        x = self.features(x)
        pooled = x.mean(dim=(2, 3))
        if self.spatial:
            quarters = F.adaptive_avg_pool2d(x, 2).flatten(1)
            pooled = torch.cat([pooled, quarters], dim=1)
        return self.head(pooled)


class WithSoftmax(nn.Module):
    def __init__(self, net):
        super().__init__()
        self.net = net

    def forward(self, crops):
        return torch.softmax(self.net(crops), dim=1)


def hue_turn(angle):
    """N x 3 x 3 matrices turning RGB colours by `angle` (radians, shape N) about the grey axis:
    hue changes, brightness and saturation stay."""
    c, s = torch.cos(angle), torch.sin(angle)
    k = 1.0 / 3.0
    r = (1.0 / 3.0) ** 0.5
    a = c + (1 - c) * k
    b = k * (1 - c) - r * s
    d = k * (1 - c) + r * s
    return torch.stack([torch.stack([a, b, d], -1), torch.stack([d, a, b], -1), torch.stack([b, d, a], -1)], -2)


def augment(xb, gen, symmetry="dihedral", hue=0.0, gain=0.08, gamma=0.0):
    """Random turn and flip, colour jitter, grey, blur-free noise, shift, and hidden masks.

    `gain` is the largest change of each colour channel's gain (0.08: +-8 %); with `gamma` > 0,
    each crop's colours are raised to a random power in [1 / (1 + gamma), 1 + gamma], which
    darkens or lightens mid-tones as other cameras and light do.

    With `hue` > 0, that share of crops has its colours turned by a random hue angle, so roof
    colour (which the renders tie to the class more than real roofs do) cannot decide alone.

    With symmetry "rect", crops with a known footprint only get the turns and flips of a
    rectangle (their long side stays horizontal); crops without one get all 8."""
    n = xb.shape[0]
    x = xb.float() / 255.0
    k = int(torch.randint(0, 4, (1,), generator=gen))
    turned = torch.rot90(x, k, dims=(2, 3))
    if symmetry == "rect" and k % 2 == 1:
        known = (x[:, 3:] != UNKNOWN).any(dim=(1, 2, 3)).view(n, 1, 1, 1)
        x = torch.where(known, torch.rot90(x, k - 1, dims=(2, 3)), turned)
    else:
        x = turned
    if torch.rand(1, generator=gen) < 0.5:
        x = torch.flip(x, dims=(3,))
    rgb, mask = x[:, :3], x[:, 3:]
    # Brightness, contrast, per-channel gain, saturation.
    b = 1 + 0.25 * (torch.rand(n, 1, 1, 1, generator=gen) * 2 - 1)
    c = 1 + 0.3 * (torch.rand(n, 1, 1, 1, generator=gen) * 2 - 1)
    g = 1 + gain * (torch.rand(n, 3, 1, 1, generator=gen) * 2 - 1)
    mean = rgb.mean(dim=(1, 2, 3), keepdim=True)
    rgb = (rgb - mean) * c + mean
    rgb = rgb * b * g
    grey = rgb.mean(dim=1, keepdim=True)
    s = 0.6 + torch.rand(n, 1, 1, 1, generator=gen) * 0.7
    s = torch.where(torch.rand(n, 1, 1, 1, generator=gen) < 0.05, torch.zeros_like(s), s)
    rgb = grey + (rgb - grey) * s
    if hue > 0:
        angle = (torch.rand(n, generator=gen) * 2 - 1) * torch.pi
        angle = torch.where(torch.rand(n, generator=gen) < hue, angle, torch.zeros_like(angle))
        rgb = torch.einsum("nij,njhw->nihw", hue_turn(angle), rgb)
    if gamma > 0:
        # A power drawn evenly in log space, so darker and lighter are equally likely.
        power = torch.exp((torch.rand(n, 1, 1, 1, generator=gen) * 2 - 1) * float(np.log1p(gamma)))
        rgb = rgb.clamp(0, 1) ** power
    rgb = rgb + 0.02 * torch.randn(rgb.shape, generator=gen) * torch.rand(n, 1, 1, 1, generator=gen)
    rgb = rgb.clamp(0, 1)
    # Hide a known mask now and then, so both paths keep training.
    hide = (torch.rand(n, 1, 1, 1, generator=gen) < 0.15) & (mask != UNKNOWN).any(dim=(2, 3), keepdim=True)
    mask = torch.where(hide, torch.full_like(mask, UNKNOWN), mask)
    x = torch.cat([rgb, mask], dim=1)
    # Shift by up to 3 px.
    dx, dy = (int(v) for v in torch.randint(-3, 4, (2,), generator=gen))
    x = torch.roll(x, shifts=(dy, dx), dims=(2, 3))
    return x


def evaluate(net, x, y, batch=512):
    net.eval()
    preds = []
    with torch.no_grad():
        for i in range(0, len(x), batch):
            xb = torch.from_numpy(x[i:i + batch]).float() / 255.0
            preds.append(net(xb).argmax(1).numpy())
    p = np.concatenate(preds)
    confusion = np.zeros((3, 3), dtype=np.int64)
    for t, q in zip(y, p):
        confusion[t, q] += 1
    return float((p == y).mean()), confusion


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--train", required=True, action="append",
                    help="a rendered set; repeat to train on several at once")
    ap.add_argument("--test", required=True)
    ap.add_argument("--out", required=True, help="the .onnx file to write")
    ap.add_argument("--metrics", required=True, help="a JSON file for the model card")
    ap.add_argument("--seed", type=int, default=20261127)
    ap.add_argument("--epochs", type=int, default=20)
    ap.add_argument("--batch", type=int, default=128)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--symmetry", choices=["dihedral", "rect"], default="dihedral")
    ap.add_argument("--spatial", action="store_true", help="a head that also sees the crop's quarters")
    ap.add_argument("--width", default="16,32,64,128")
    ap.add_argument("--deep", action="store_true", help="a second convolution at 8 x 8")
    ap.add_argument("--residual", type=int, default=0, help="residual blocks added at 8 x 8")
    ap.add_argument("--hue", type=float, default=0.0, help="share of crops whose hue is turned at random")
    ap.add_argument("--init", help="start from this trained state dict (train.py writes one beside --metrics)")
    ap.add_argument("--gain", type=float, default=0.08, help="largest change of a colour channel's gain")
    ap.add_argument("--gamma", type=float, default=0.0, help="random gamma in [1 / (1 + G), 1 + G]")
    ap.add_argument("--lr", type=float, default=3e-3, help="the peak learning rate")
    args = ap.parse_args()

    torch.manual_seed(args.seed)
    np.random.seed(args.seed)
    torch.set_num_threads(args.threads)
    gen = torch.Generator().manual_seed(args.seed)

    sets = [load(folder) for folder in args.train]
    x = np.concatenate([s[0] for s in sets]) if len(sets) > 1 else sets[0][0]
    y = np.concatenate([s[1] for s in sets]) if len(sets) > 1 else sets[0][1]
    del sets
    xt, yt = load(args.test)
    print(f"train {len(x)} crops, test {len(xt)} crops", flush=True)
    net = RoofNet(tuple(int(w) for w in args.width.split(",")), spatial=args.spatial, deep=args.deep,
                  residual=args.residual)
    if args.init:
        # Blocks the saved net does not have (--residual) start as the identity.
        missing, unexpected = net.load_state_dict(torch.load(args.init), strict=False)
        assert not unexpected and all(".body." in k for k in missing), (missing, unexpected)
        print(f"starting from {args.init}; new: {len(missing)} tensors", flush=True)
    params = sum(p.numel() for p in net.parameters())
    print(f"{params} parameters", flush=True)
    steps = args.epochs * (len(x) // args.batch)
    opt = torch.optim.AdamW(net.parameters(), lr=args.lr, weight_decay=5e-4)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=args.lr, total_steps=steps, pct_start=0.15)
    started = time.time()
    step = 0
    for epoch in range(args.epochs):
        net.train()
        order = torch.randperm(len(x), generator=gen).numpy()
        total, correct, loss_sum = 0, 0, 0.0
        for i in range(0, len(order) - args.batch + 1, args.batch):
            idx = order[i:i + args.batch]
            xb = augment(torch.from_numpy(x[idx]), gen, args.symmetry, args.hue, args.gain, args.gamma)
            yb = torch.from_numpy(y[idx])
            logits = net(xb)
            loss = F.cross_entropy(logits, yb, label_smoothing=0.05)
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            step += 1
            loss_sum += loss.item() * len(idx)
            correct += int((logits.argmax(1) == yb).sum())
            total += len(idx)
        acc, _ = evaluate(net, xt, yt)
        print(f"epoch {epoch + 1}/{args.epochs}: loss {loss_sum / total:.3f}, train acc {correct / total:.3f}, "
              f"test acc {acc:.3f}, {time.time() - started:.0f} s", flush=True)

    minutes = (time.time() - started) / 60
    acc, confusion = evaluate(net, xt, yt)
    print(f"test accuracy {acc:.4f}\n{confusion}", flush=True)

    net.eval()
    model = WithSoftmax(net).eval()
    sample = torch.from_numpy(xt[:64]).float() / 255.0
    with torch.no_grad():
        want = model(sample).numpy()
    torch.save(net.state_dict(), os.path.splitext(args.metrics)[0] + ".pt")
    dummy = torch.zeros(1, 4, SIZE, SIZE)
    torch.onnx.export(model, dummy, args.out, input_names=["crops"], output_names=["probabilities"],
                      dynamic_axes={"crops": {0: "n"}, "probabilities": {0: "n"}}, opset_version=17,
                      dynamo=False)

    # The exported model must answer as torch does.
    import onnxruntime as ort
    # The exporter puts the module back into training mode afterwards: compare with the
    # answers taken before it.
    sess = ort.InferenceSession(args.out, providers=["CPUExecutionProvider"])
    got = sess.run(None, {"crops": sample.numpy()})[0]
    diff = float(np.abs(want - got).max())
    print(f"onnxruntime vs torch: max difference {diff:.2e}", flush=True)
    assert diff < 1e-4

    per_mask = {}
    for name, sel in [("with mask", xt[:, 3, 0, 0] != 128), ("without mask", xt[:, 3, 0, 0] == 128)]:
        a, c = evaluate(net, xt[sel], yt[sel])
        per_mask[name] = {"count": int(sel.sum()), "accuracy": a, "confusion": c.tolist()}
    json.dump({
        "classes": CLASSES,
        "parameters": params,
        "epochs": args.epochs,
        "batch": args.batch,
        "seed": args.seed,
        "threads": args.threads,
        "train_crops": int(len(x)),
        "test_crops": int(len(xt)),
        "training_minutes": round(minutes, 1),
        "test_accuracy": acc,
        "confusion": confusion.tolist(),
        "by_mask": per_mask,
        "torch": torch.__version__,
    }, open(args.metrics, "w"), indent=2)


if __name__ == "__main__":
    main()

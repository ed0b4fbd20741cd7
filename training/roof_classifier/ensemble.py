"""Joins several trained roof classifiers into one ONNX model that answers the mean of their class
probabilities. Same input and output as a single model (N x 4 x 64 x 64 crops -> N x 3
probabilities), so citymesh runs it unchanged.

    .venv-train/bin/python training/roof_classifier/ensemble.py OUT.onnx MEMBER...

Each MEMBER is `STATE.pt:WIDTH[:spatial][:deep][:residual]`: the state dict `train.py` saved beside its
metrics file, and the options it was trained with, e.g.
`target/roof_classifier/a/training.pt:16,32,64,128:spatial`.
"""

import sys

import numpy as np
import torch
import torch.nn as nn

from train import SIZE, RoofNet


class Mean(nn.Module):
    def __init__(self, nets):
        super().__init__()
        self.nets = nn.ModuleList(nets)

    def forward(self, crops):
        return torch.stack([torch.softmax(n(crops), dim=1) for n in self.nets]).mean(dim=0)


def member(spec):
    path, width, *flags = spec.split(":")
    unknown = set(flags) - {"spatial", "deep", "residual"}
    if unknown:
        sys.exit(f"error: unknown option {sorted(unknown)} in {spec}")
    net = RoofNet(tuple(int(w) for w in width.split(",")), spatial="spatial" in flags, deep="deep" in flags,
                  residual=int("residual" in flags))
    net.load_state_dict(torch.load(path, map_location="cpu"))
    return net.eval()


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    out, specs = sys.argv[1], sys.argv[2:]
    model = Mean([member(s) for s in specs]).eval()
    torch.manual_seed(0)
    sample = torch.rand(16, 4, SIZE, SIZE)
    with torch.no_grad():
        want = model(sample).numpy()
    torch.onnx.export(model, torch.zeros(1, 4, SIZE, SIZE), out, input_names=["crops"],
                      output_names=["probabilities"],
                      dynamic_axes={"crops": {0: "n"}, "probabilities": {0: "n"}}, opset_version=17,
                      dynamo=False)
    import onnxruntime as ort
    got = ort.InferenceSession(out, providers=["CPUExecutionProvider"]).run(None, {"crops": sample.numpy()})[0]
    diff = float(np.abs(want - got).max())
    print(f"{len(specs)} members, {sum(p.numel() for p in model.parameters())} parameters; "
          f"onnxruntime vs torch: max difference {diff:.2e}", flush=True)
    assert diff < 1e-4


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Rebuild an Ultralytics checkpoint (.pt) from one of this project's ONNX exports.

The ONNX export is the network with every batch norm folded into its
convolution. Folding is invertible up to the batch norm's own statistics:
each convolution gets the folded weight W and its batch norm adds the folded
bias b. A batch norm that only adds b would compute the export exactly in
inference, but in training it normalizes by each batch's statistics and the
network would start far from where it was. So the statistics are measured:
the export's convolutions run over --calibration images, each channel's mean
m and variance v of W*x are recorded, and the batch norm gets running mean m,
running variance v, scale sqrt(v + eps) and shift m + b. That is still
exactly W*x + b in inference, and close to it on a training batch. This lets
training go on from a shipped model whose checkpoint was lost.

    .venv-train/bin/python training/onnx_to_pt.py --onnx models/towers.onnx \
        --calibration target/train/dataset/images/train --out models/towers.pt

It checks the rebuilt network against ONNX Runtime on random inputs and
fails when they differ.
"""

from __future__ import annotations

import argparse
import ast
import os
import sys
from pathlib import Path


def parse_args() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--onnx", type=Path, required=True, help="an Ultralytics ONNX export (names in its metadata)")
    p.add_argument("--out", type=Path, required=True, help="checkpoint to write")
    p.add_argument("--model", default="yolov5n.yaml", help="the architecture the export was trained as")
    p.add_argument("--calibration", type=Path, help="training images whose statistics the batch norms take")
    p.add_argument("--calibration-images", type=int, default=96)
    return p.parse_args()


def main() -> int:
    args = parse_args()
    os.environ.setdefault("YOLO_CONFIG_DIR", str(args.out.resolve().parent / ".ultralytics-config"))
    os.environ["YOLO_OFFLINE"] = "1"
    import numpy as np
    import onnx
    import onnxruntime as ort
    import torch
    from onnx import numpy_helper

    exported = onnx.load(str(args.onnx))
    meta = {p.key: p.value for p in exported.metadata_props}
    if "names" not in meta:
        print(f"error: {args.onnx} has no class names in its metadata (not an Ultralytics export?)", file=sys.stderr)
        return 2
    names = ast.literal_eval(meta["names"])
    folded = {i.name: torch.from_numpy(numpy_helper.to_array(i).copy()) for i in exported.graph.initializer}

    from ultralytics.nn.tasks import DetectionModel

    net = DetectionModel(args.model, nc=len(names), verbose=False)
    net.names = names
    state = net.state_dict()
    loaded = set()
    for key in list(state):
        stem = key[: -len(".conv.weight")]
        if key.endswith(".conv.weight") and key in folded and stem + ".bn.weight" in state:
            state[key] = folded[key]
            loaded.add(key)
            bias = folded.get(stem + ".conv.bias")
            bn = net.get_submodule(stem + ".bn")
            if bias is None:
                print(f"error: {args.onnx} has {key} but no {stem}.conv.bias", file=sys.stderr)
                return 1
            state[stem + ".bn.weight"] = torch.ones_like(bias)
            state[stem + ".bn.bias"] = bias
            state[stem + ".bn.running_mean"] = torch.zeros_like(bias)
            state[stem + ".bn.running_var"] = torch.full_like(bias, 1.0 - bn.eps)
            loaded.add(stem + ".conv.bias")
        elif key in folded:
            if state[key].shape != folded[key].shape:
                print(f"error: {key} is {tuple(folded[key].shape)} in the export, {tuple(state[key].shape)} here", file=sys.stderr)
                return 1
            state[key] = folded[key]
            loaded.add(key)
    unused = [k for k in folded if k not in loaded and ("weight" in k or "bias" in k)]
    if unused:
        print(f"error: the export's {unused[:5]} match nothing in {args.model}", file=sys.stderr)
        return 1
    net.load_state_dict(state)
    net.eval()

    h, w = ast.literal_eval(meta.get("imgsz", "[320, 512]"))
    if args.calibration:
        calibrate(net, args.calibration, args.calibration_images, h, w)
    session = ort.InferenceSession(str(args.onnx), providers=["CPUExecutionProvider"])
    rng = np.random.default_rng(0)
    worst = 0.0
    for _ in range(3):
        x = rng.random((1, 3, h, w), dtype=np.float32)
        want = session.run(None, {session.get_inputs()[0].name: x})[0]
        with torch.no_grad():
            got = net(torch.from_numpy(x))[0].numpy()
        worst = max(worst, float(np.abs(want - got).max() / (np.abs(want).max() + 1e-9)))
    print(f"rebuilt {len(loaded)} tensors of {args.onnx}; largest difference from ONNX Runtime: {worst:.2e} of the output's range")
    if worst > 1e-3:
        print("error: the rebuilt network does not compute what the export does", file=sys.stderr)
        return 1

    # The layout Ultralytics writes and reads back (`YOLO(path)`, `train(model=path)`).
    net.args = {"model": args.model, "imgsz": max(h, w), "task": "detect"}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    torch.save({"model": net, "ema": None, "epoch": -1, "train_args": net.args, "date": meta.get("date")}, args.out)
    print(f"wrote {args.out}")
    return 0


def calibrate(net, folder: Path, count: int, h: int, w: int) -> None:
    """Give each batch norm its convolution's measured output statistics, keeping the function."""
    import numpy as np
    import torch
    from PIL import Image

    paths = sorted(p for p in folder.iterdir() if p.suffix.lower() in (".jpg", ".jpeg", ".png"))
    if not paths:
        raise SystemExit(f"error: no images in {folder}")
    step = max(1, len(paths) // count)
    batch = torch.stack(
        [
            torch.from_numpy(np.asarray(Image.open(p).convert("RGB").resize((w, h)), dtype=np.float32) / 255.0).permute(2, 0, 1)
            for p in paths[::step][:count]
        ]
    )
    stats = {}
    hooks = []
    for name, module in net.named_modules():
        if hasattr(module, "conv") and hasattr(module, "bn"):
            conv = module.conv

            def hook(mod, inputs, output, name=name):
                y = output.detach().double()
                s1 = y.sum(dim=(0, 2, 3))
                s2 = (y * y).sum(dim=(0, 2, 3))
                n = y.shape[0] * y.shape[2] * y.shape[3]
                acc = stats.setdefault(name, [0.0, 0.0, 0])
                acc[0] = acc[0] + s1
                acc[1] = acc[1] + s2
                acc[2] += n

            hooks.append(conv.register_forward_hook(hook))
    with torch.no_grad():
        for chunk in batch.split(8):
            net(chunk)
    for h_ in hooks:
        h_.remove()
    for name, (s1, s2, n) in stats.items():
        bn = net.get_submodule(name).bn
        mean = (s1 / n).float()
        var = (s2 / n - (s1 / n) ** 2).clamp(min=1e-6).float()
        bias = bn.bias.data.clone()
        bn.running_mean.copy_(mean)
        bn.running_var.copy_(var)
        bn.weight.data.copy_(torch.sqrt(var + bn.eps))
        bn.bias.data.copy_(mean + bias)
    print(f"calibrated {len(stats)} batch norms on {batch.shape[0]} images of {folder}")


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""Start the tower detector from COCO-trained features.

The COCO-trained YOLOv5n checkpoint (`../shared/weights/coco/yolov5n.pt`) is
a pickle of the classes of the old `yolov5` repository, which is not installed
here: it is read with stand-in classes for the unpickler, and only its tensors
are kept. Its backbone and neck (layers 0-23) map one to one onto Ultralytics'
own `yolov5n.yaml`; its anchor-based Detect head does not fit Ultralytics'
anchor-free head, so that head starts fresh.

    coco_init.py init --weights ../shared/weights/coco/yolov5n.pt --names tower --out coco-init.pt
        an Ultralytics checkpoint `train.py --init` (and `cargo xtask train
        --init coco`) starts from;
    coco_init.py check-onnx --weights ../shared/weights/coco/yolov5n.pt --out coco-check.onnx
        the converted backbone and neck with the checkpoint's own anchor head
        for a few COCO classes, exported in the YOLOv5 layout `[1, N, 5 + C]`:
        what the project's ONNX runtime runs on `bus.jpg` to show that the
        mapping kept the features (people and a bus must still be found).
"""

from __future__ import annotations

import argparse
import os
import pickle
import sys
import types
from pathlib import Path

# The last layer before the Detect head, in both trees.
LAST_SHARED_LAYER = 23
# Classes the check model keeps: the ones `bus.jpg` and `zidane.jpg` show, and their neighbours.
CHECK_CLASSES = ("person", "bicycle", "car", "motorcycle", "bus", "truck", "tie")


class ConversionError(Exception):
    pass


def _stand_in_unpickler():
    """A pickle module whose Unpickler builds plain `nn.Module`s for the old
    tree's classes (`models.*`, `utils.*`): their state is their tensors."""
    import torch.nn as nn

    made: dict[tuple[str, str], type] = {}

    class StandIn(pickle.Unpickler):
        def find_class(self, module, name):
            if module.split(".")[0] in ("models", "utils"):
                key = (module, name)
                if key not in made:
                    made[key] = type(name, (nn.Module,), {"__module__": f"stand_in.{module}"})
                return made[key]
            return super().find_class(module, name)

    module = types.ModuleType("stand_in_pickle")
    module.Unpickler = StandIn
    module.load = pickle.load
    module.__dict__["Pickler"] = pickle.Pickler
    return module


class Yolov5Checkpoint:
    """What the old checkpoint holds that the conversion needs."""

    def __init__(self, path: Path):
        import torch

        if not path.is_file():
            raise ConversionError(f"{path}: no such checkpoint (see ../shared/weights/README.md)")
        try:
            ckpt = torch.load(path, map_location="cpu", pickle_module=_stand_in_unpickler(), weights_only=False)
        except Exception as e:  # noqa: BLE001 - any unpickling failure is a bad file
            raise ConversionError(f"{path}: not a YOLOv5 checkpoint: {e}") from e
        model = (ckpt.get("ema") or ckpt.get("model")) if isinstance(ckpt, dict) else None
        if model is None or not hasattr(model, "state_dict"):
            raise ConversionError(f"{path}: holds no `model` (keys: {list(ckpt)[:8] if isinstance(ckpt, dict) else type(ckpt)})")
        self.state = {k: v.float() if v.is_floating_point() else v for k, v in model.state_dict().items()}
        names = getattr(model, "names", None)
        self.names = [names[i] for i in sorted(names)] if isinstance(names, dict) else list(names or [])
        self.yaml = getattr(model, "yaml", {}) or {}
        head = model.model[-1]
        self.strides = [float(s) for s in head.stride]
        # Anchors are kept in grid cells; in pixels they are times the stride.
        self.anchors_px = (self.state[f"model.{LAST_SHARED_LAYER + 1}.anchors"] * head.stride.float().view(-1, 1, 1)).tolist()
        if len(self.names) != int(self.yaml.get("nc", len(self.names))):
            raise ConversionError(f"{path}: {len(self.names)} names for nc={self.yaml.get('nc')}")

    def shared_layers(self) -> dict:
        """Backbone and neck: every tensor of layers 0-23."""
        keep = {}
        for key, value in self.state.items():
            layer = int(key.split(".")[1])
            if layer <= LAST_SHARED_LAYER:
                keep[key] = value
        return keep


def is_old_tree_checkpoint(path: Path) -> bool:
    """Whether `path` pickles the old `yolov5` tree's classes (not Ultralytics')."""
    import zipfile

    try:
        with zipfile.ZipFile(path) as z:
            pickled = next((n for n in z.namelist() if n.endswith("data.pkl")), None)
            data = z.read(pickled) if pickled else b""
    except (OSError, zipfile.BadZipFile):
        return False
    return b"models.yolo" in data and b"ultralytics" not in data


def ultralytics_yolov5n(nc: int):
    """Ultralytics' own YOLOv5n, built from its yaml (no download)."""
    from ultralytics.nn.tasks import DetectionModel

    return DetectionModel("yolov5n.yaml", nc=nc, verbose=False)


def load_shared(model, source: Yolov5Checkpoint) -> int:
    """Copies layers 0-23 into `model`; every tensor must find its twin of the same shape."""
    target = model.state_dict()
    shared = source.shared_layers()
    missing = [k for k in target if int(k.split(".")[1]) <= LAST_SHARED_LAYER and k not in shared]
    extra = [k for k in shared if k not in target]
    wrong = [k for k in shared if k in target and target[k].shape != shared[k].shape]
    if missing or extra or wrong:
        raise ConversionError(
            f"the checkpoint does not map onto Ultralytics' yolov5n: {len(missing)} missing "
            f"(first {missing[:3]}), {len(extra)} unknown ({extra[:3]}), {len(wrong)} of another shape ({wrong[:3]})"
        )
    target.update(shared)
    model.load_state_dict(target)
    return len(shared)


def init_checkpoint(weights: Path, names: list[str], out: Path) -> dict:
    """Writes an Ultralytics checkpoint with COCO features and a fresh head for `names`."""
    import torch
    from ultralytics import __version__ as ultralytics_version

    source = Yolov5Checkpoint(weights)
    model = ultralytics_yolov5n(len(names))
    tensors = load_shared(model, source)
    model.names = dict(enumerate(names))
    model.args = {"imgsz": 640, "task": "detect"}
    out.parent.mkdir(parents=True, exist_ok=True)
    torch.save(
        {
            "model": model.half(),
            "ema": None,
            "updates": 0,
            "optimizer": None,
            "epoch": -1,
            "train_args": {"model": "yolov5n.yaml", "task": "detect", "imgsz": 640},
            "version": ultralytics_version,
            "date": "",
            "towernav_init": {"from": str(weights), "tensors": tensors, "head": "fresh"},
        },
        out,
    )
    return {"tensors": tensors, "names": names, "out": str(out)}


def check_module(source: Yolov5Checkpoint, classes: list[str]):
    """The converted backbone and neck ahead of the checkpoint's own anchor head,
    kept for `classes` only; decoded to `[1, N, 5 + C]` in input pixels."""
    import torch
    import torch.nn as nn

    unknown = [c for c in classes if c not in source.names]
    if unknown:
        raise ConversionError(f"classes {unknown} are not among the checkpoint's {len(source.names)}")
    body = ultralytics_yolov5n(len(source.names))
    load_shared(body, source)
    body.eval()
    head = LAST_SHARED_LAYER + 1
    per_anchor = 5 + len(source.names)
    keep = [0, 1, 2, 3, 4] + [5 + source.names.index(c) for c in classes]

    class Check(nn.Module):
        def __init__(self):
            super().__init__()
            self.layers = body.model[:head]
            self.save = set(body.save)
            self.inputs = list(body.model[head].f)
            self.heads = nn.ModuleList()
            for level in range(len(source.strides)):
                w = source.state[f"model.{head}.m.{level}.weight"]
                b = source.state[f"model.{head}.m.{level}.bias"]
                rows = [a * per_anchor + k for a in range(len(source.anchors_px[level])) for k in keep]
                conv = nn.Conv2d(w.shape[1], len(rows), 1)
                conv.weight.data = w[rows].clone()
                conv.bias.data = b[rows].clone()
                self.heads.append(conv)
            self.strides = source.strides
            self.anchors = [torch.tensor(a) for a in source.anchors_px]
            self.no = len(keep)

        def forward(self, x):
            outputs = []
            for m in self.layers:
                if m.f != -1:
                    x = outputs[m.f] if isinstance(m.f, int) else [x if j == -1 else outputs[j] for j in m.f]
                x = m(x)
                outputs.append(x if m.i in self.save else None)
            decoded = []
            for level, conv in enumerate(self.heads):
                y = conv(outputs[self.inputs[level]])
                bs, _, h, w = y.shape
                na = len(self.anchors[level])
                y = y.view(bs, na, self.no, h, w).permute(0, 1, 3, 4, 2).sigmoid()
                gy, gx = torch.meshgrid(torch.arange(h), torch.arange(w), indexing="ij")
                grid = torch.stack((gx, gy), -1).view(1, 1, h, w, 2).float()
                anchor = self.anchors[level].view(1, na, 1, 1, 2)
                xy = (y[..., :2] * 2 - 0.5 + grid) * self.strides[level]
                wh = (y[..., 2:4] * 2) ** 2 * anchor
                decoded.append(torch.cat((xy, wh, y[..., 4:]), -1).view(bs, -1, self.no))
            return torch.cat(decoded, 1)

    return Check().eval()


def export_check(weights: Path, out: Path, classes: list[str], size: int) -> dict:
    import torch
    import onnx

    source = Yolov5Checkpoint(weights)
    module = check_module(source, classes)
    out.parent.mkdir(parents=True, exist_ok=True)
    dummy = torch.zeros(1, 3, size, size)
    with torch.no_grad():
        shape = list(module(dummy).shape)
        torch.onnx.export(module, dummy, str(out), opset_version=17, input_names=["images"], output_names=["output0"], dynamo=False)
    model = onnx.load(str(out))
    names = "{" + ", ".join(f"{i}: '{c}'" for i, c in enumerate(classes)) + "}"
    for key, value in (("names", names), ("stride", "32"), ("imgsz", f"[{size}, {size}]"), ("description", "YOLOv5n COCO check: converted backbone and neck, the checkpoint's own head")):
        entry = model.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.save(model, str(out))
    return {"out": str(out), "output_shape": shape, "classes": classes}


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True)
    init = sub.add_parser("init", help="an Ultralytics checkpoint with COCO features and a fresh head")
    init.add_argument("--weights", type=Path, required=True)
    init.add_argument("--names", default="tower", help="the new model's class names, comma-separated")
    init.add_argument("--out", type=Path, required=True)
    check = sub.add_parser("check-onnx", help="the converted network with the COCO head, as ONNX")
    check.add_argument("--weights", type=Path, required=True)
    check.add_argument("--out", type=Path, required=True)
    check.add_argument("--classes", default=",".join(CHECK_CLASSES))
    check.add_argument("--size", type=int, default=640)
    return p.parse_args(argv)


def main(argv=None) -> int:
    args = parse_args(argv)
    os.environ.setdefault("YOLO_OFFLINE", "1")
    try:
        if args.command == "init":
            names = [n.strip() for n in args.names.split(",") if n.strip()]
            if not names:
                raise ConversionError("--names: at least one class")
            print(init_checkpoint(args.weights, names, args.out))
        else:
            print(export_check(args.weights, args.out, args.classes.split(","), args.size))
    except ConversionError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())

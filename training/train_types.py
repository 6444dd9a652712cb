#!/usr/bin/env python3
"""Train towernav's tower-type classifier: the second stage of the detector.

The detector runs on the frame shrunk to 512x320, where a 40 px tower is
16 px tall and its lattice arms blur together: it finds towers far better
than it tells their types apart. This classifier looks again at each box in
the full-resolution frame and names the type.

Each crop is the square centred on the box, side `PAD` times the box's longer
edge, grey (114) outside the frame, resized to --imgsz square. The edge
(`towernav-edge`, `detector::type_crop`) cuts its crops exactly the same way.

    .venv-train/bin/python training/train_types.py --data target/train/dataset --out target/train/types

It cuts the crops from the detector's YOLO dataset (train and val worlds for
training and validation, test worlds held out), trains Ultralytics'
`yolov8n-cls.yaml` from scratch on the CPU, exports ONNX (opset 17, class
names in the metadata) and evaluates on the test crops.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import sys
import time
from pathlib import Path

#: Crop side over the box's longer edge; keep equal to the edge's `CROP_PAD`.
PAD = 1.15
GREY = (114, 114, 114)


def parse_args() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", type=Path, required=True, help="detector dataset folder holding data.yaml")
    p.add_argument("--out", type=Path, required=True, help="run folder (crops, checkpoints, export, metrics)")
    p.add_argument("--model", default="yolov8n-cls.yaml", help="Ultralytics classifier (built from scratch)")
    p.add_argument("--imgsz", type=int, default=64, help="crop side, a multiple of 32 (Ultralytics rounds it up to one)")
    p.add_argument("--min-height", type=float, default=16.0, help="smallest box (full-resolution px) cropped")
    p.add_argument("--jitter", type=float, default=0.08, help="training crops: random shift and size, fraction of the side")
    p.add_argument("--epochs", type=int, default=12)
    p.add_argument("--hours", type=float, default=0.5, help="wall-clock budget for the training loop")
    p.add_argument("--batch", type=int, default=64)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--threads", type=int, default=os.cpu_count() or 2)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--init", type=Path, help="continue from these weights (an earlier run's best.pt) instead of from scratch")
    return p.parse_args()


def read_names(data_yaml: Path) -> dict[int, str]:
    """Class names from data.yaml's `names:` block (`  0: A` lines)."""
    names: dict[int, str] = {}
    in_names = False
    for line in data_yaml.read_text().splitlines():
        if line.startswith("names:"):
            in_names = True
            continue
        if in_names:
            if not line.startswith(" "):
                break
            key, _, value = line.strip().partition(":")
            names[int(key)] = value.strip()
    if not names:
        raise SystemExit(f"error: no `names:` in {data_yaml}")
    return names


def square_crop(image, cx: float, cy: float, side: float, size: int):
    """The square centred on (cx, cy), grey outside the frame, resized to size x size."""
    from PIL import Image

    x0, y0 = round(cx - side / 2), round(cy - side / 2)
    s = max(1, round(side))
    canvas = Image.new("RGB", (s, s), GREY)
    canvas.paste(image.crop((max(0, x0), max(0, y0), min(image.width, x0 + s), min(image.height, y0 + s))), (max(0, -x0), max(0, -y0)))
    return canvas.resize((size, size), Image.BILINEAR)


def cut_crops(data: Path, crops: Path, names: dict[int, str], args: argparse.Namespace) -> dict[str, int]:
    """One crop per labelled tower at least --min-height tall, split as the detector's worlds are."""
    from PIL import Image

    rng = random.Random(args.seed)
    counts: dict[str, int] = {}
    for split in ("train", "val", "test"):
        for name in names.values():
            (crops / split / name).mkdir(parents=True, exist_ok=True)
        n = 0
        for img_path in sorted((data / "images" / split).glob("*.jpg")):
            label_path = data / "labels" / split / (img_path.stem + ".txt")
            if not label_path.exists():
                continue
            image = Image.open(img_path).convert("RGB")
            w, h = image.size
            for k, line in enumerate(label_path.read_text().splitlines()):
                fields = line.split()
                if len(fields) != 5:
                    continue
                cls = int(fields[0])
                cx, cy, bw, bh = (float(v) for v in fields[1:])
                cx, cy, bw, bh = cx * w, cy * h, bw * w, bh * h
                if bh < args.min_height or cls not in names:
                    continue
                side = PAD * max(bw, bh)
                if split == "train":
                    # The detector's boxes are a little off: teach the classifier that.
                    j = args.jitter
                    cx += rng.uniform(-j, j) * side
                    cy += rng.uniform(-j, j) * side
                    side *= rng.uniform(1.0 - j, 1.0 + j)
                crop = square_crop(image, cx, cy, side, args.imgsz)
                crop.save(crops / split / names[cls] / f"{img_path.stem}_{k:02d}.png")
                n += 1
        counts[split] = n
    return counts


def fix_crop_size(src: Path, dst: Path, size: int) -> None:
    """Pin the input's height and width (the export leaves them dynamic with
    the batch): the edge reads the crop size from the model."""
    import onnx

    model = onnx.load(str(src))
    dims = model.graph.input[0].type.tensor_type.shape.dim
    for d in dims[2:]:
        d.ClearField("dim_param")
        d.dim_value = size
    onnx.checker.check_model(model)
    onnx.save(model, str(dst))


def main() -> int:
    args = parse_args()
    out = args.out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    os.environ.setdefault("YOLO_CONFIG_DIR", str(out / "ultralytics-config"))
    os.environ["YOLO_OFFLINE"] = "1"
    import torch
    from ultralytics import YOLO, settings

    settings.update({"sync": False})
    torch.set_num_threads(args.threads)

    data_yaml = (args.data / "data.yaml").resolve()
    if not data_yaml.is_file():
        print(f"error: {data_yaml} not found; render it with `towernav-sim dataset --out {args.data}`", file=sys.stderr)
        return 2
    names = read_names(data_yaml)

    crops = out / "crops"
    counts_file = out / "crops.json"
    if not counts_file.exists():
        if crops.exists():
            shutil.rmtree(crops)
        started = time.time()
        counts = cut_crops(args.data.resolve(), crops, names, args)
        counts_file.write_text(json.dumps(counts) + "\n")
        print(f"cut {counts} crops in {time.time() - started:.0f} s")
    counts = json.loads(counts_file.read_text())

    run_dir = out / "train"
    last = run_dir / "weights" / "last.pt"
    best = run_dir / "weights" / "best.pt"
    done_marker = out / "train.done"
    started = time.time()
    if done_marker.exists() and best.exists():
        print(f"training already finished ({best}); exporting and evaluating only")
    elif last.exists():
        print(f"resuming from {last}")
        YOLO(str(last)).train(resume=True)
        done_marker.write_text("ok\n")
    else:
        if run_dir.exists():
            shutil.rmtree(run_dir)
        # A .yaml builds a random init (no download); --init continues from
        # an earlier run's weights.
        model = YOLO(str(args.init) if args.init else args.model)
        model.train(
            data=str(crops),
            epochs=args.epochs,
            time=args.hours,
            imgsz=args.imgsz,
            batch=args.batch,
            workers=args.workers,
            device="cpu",
            cache="ram",
            pretrained=bool(args.init),
            amp=False,
            plots=False,
            project=str(out),
            name="train",
            exist_ok=True,
            seed=args.seed,
            deterministic=False,
            patience=100,
            warmup_epochs=1.0,
            # Crops are already square and centred: keep the whole tower in view.
            scale=0.1,
            fliplr=0.5,
            erasing=0.0,
            auto_augment=None,
            verbose=True,
        )
        done_marker.write_text("ok\n")
    train_s = time.time() - started

    if not best.exists():
        print(f"error: no {best} after training", file=sys.stderr)
        return 1
    model = YOLO(str(best))
    onnx_path = Path(model.export(format="onnx", opset=17, imgsz=args.imgsz, simplify=True, dynamic=True, device="cpu"))
    exported = out / "tower-types.onnx"
    fix_crop_size(onnx_path, exported, args.imgsz)

    metrics = {}
    for split in ("val", "test"):
        r = model.val(data=str(crops), split=split, imgsz=args.imgsz, batch=args.batch, device="cpu", plots=False, project=str(out), name=f"val-{split}", exist_ok=True)
        metrics[split] = {"top1": float(r.top1)}
    summary = {
        "model": args.model,
        "init": str(args.init) if args.init else None,
        "imgsz": args.imgsz,
        "crop_pad": PAD,
        "min_height_px": args.min_height,
        "classes": model.names,
        "crops": counts,
        "train_loop_seconds_this_call": round(train_s, 1),
        "onnx": str(exported),
        "onnx_bytes": exported.stat().st_size,
        "ultralytics_metrics": metrics,
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(json.dumps(summary, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""Train towernav's tower detector on the simulator's YOLO dataset: fine-tune
from --init (the shipped `models/towers.pt`, as `cargo xtask train` passes it),
or from scratch without it.

Run through `cargo xtask train` (which renders the dataset and installs the
pinned environment first), or by hand:

    .venv-train/bin/python training/train.py --data target/train/dataset --out target/train/run

It trains a YOLOv5-family model (Ultralytics `yolov5n.yaml`; no outside
weights: nothing can be downloaded here) on the CPU, or a GPU with
`--device 0`, within a wall-clock budget; it resumes from `last.pt` when a
run was interrupted, exports ONNX (opset 17, class names in the metadata) at
the edge's input size, and evaluates on the held-out test worlds. Everything
it writes stays under --out.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import time
from pathlib import Path


def parse_args() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", type=Path, required=True, help="dataset folder holding data.yaml")
    p.add_argument("--out", type=Path, required=True, help="run folder (checkpoints, export, metrics)")
    p.add_argument("--model", default="yolov5n.yaml", help="Ultralytics architecture (built from scratch)")
    p.add_argument("--imgsz", type=int, default=512, help="training size (square mosaics)")
    p.add_argument("--export-h", type=int, default=320, help="exported input height (1280x720 letterboxed)")
    p.add_argument("--export-w", type=int, default=512, help="exported input width")
    p.add_argument("--hours", type=float, default=1.6, help="wall-clock budget for the training loop")
    p.add_argument("--epochs", type=int, default=60, help="upper bound; the time budget usually ends first")
    p.add_argument(
        "--device",
        default=os.environ.get("TOWERNAV_TRAIN_DEVICE", "cpu"),
        help="training device: cpu, or a CUDA index such as 0 (default: $TOWERNAV_TRAIN_DEVICE, else cpu)",
    )
    p.add_argument("--batch", type=int, help="default 8 on the CPU (more steps in a short budget), 64 on a GPU")
    p.add_argument("--workers", type=int, help="data loader processes (default 2 on the CPU, all cores but two on a GPU)")
    p.add_argument("--threads", type=int, default=os.cpu_count() or 2)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--freeze",
        type=int,
        default=int(os.environ.get("TOWERNAV_TRAIN_FREEZE", "0")),
        help="train first with this many leading layers frozen (10: YOLOv5n's backbone), then all",
    )
    p.add_argument("--frozen-share", type=float, default=0.3, help="share of --hours spent frozen")
    p.add_argument(
        "--init",
        type=Path,
        help="start from this checkpoint: the project's own (models/towers.pt, an earlier stage's best.pt) "
        "or the old yolov5 tree's COCO checkpoint, converted by coco_init.py",
    )
    return p.parse_args()


def every_core(model, torch, threads: int):
    """Ultralytics sets CPU training to all cores but one, which on two cores
    leaves half the machine idle; set the threads back once it has."""
    model.add_callback("on_pretrain_routine_start", lambda _trainer: torch.set_num_threads(threads))
    return model


COCO_INIT_NAME = "coco-init.pt"


def resolve_init(init: Path | None, out: Path) -> Path | None:
    """An Ultralytics checkpoint as it is; the old `yolov5` tree's COCO
    checkpoint converted first (`coco_init.py`: backbone and neck, fresh head)."""
    if init is None:
        return None
    import coco_init

    if not coco_init.is_old_tree_checkpoint(init):
        return init
    converted = out / COCO_INIT_NAME
    if not converted.exists():
        print(coco_init.init_checkpoint(init, ["tower"], converted))
    return converted


def run_phase(args, out: Path, name: str, init: Path | None, freeze: int, hours: float, fresh_head: bool, torch, YOLO, data_yaml: Path):
    """One training phase in `out/name`, resumed from its `last.pt` after an
    interruption; returns its best weights, None if it left none."""
    run_dir = out / name
    last = run_dir / "weights" / "last.pt"
    best = run_dir / "weights" / "best.pt"
    done_marker = out / f"{name}.done"
    if done_marker.exists() and best.exists():
        print(f"phase {name} already finished ({best})")
        return best
    if last.exists():
        print(f"resuming phase {name} from {last}")
        every_core(YOLO(str(last)), torch, args.threads).train(resume=True)
    else:
        if run_dir.exists():
            shutil.rmtree(run_dir)
        # A .yaml builds a random init (no download); --init continues from a
        # checkpoint (an earlier stage, or the converted COCO start).
        model = every_core(YOLO(str(init) if init else args.model), torch, args.threads)
        model.train(
            data=str(data_yaml),
            epochs=args.epochs,
            time=hours,
            imgsz=args.imgsz,
            batch=args.batch,
            workers=args.workers,
            device=args.device,
            cache="ram",
            pretrained=bool(init),
            freeze=freeze or None,
            amp=False,
            plots=False,
            project=str(out),
            name=name,
            exist_ok=True,
            seed=args.seed,
            deterministic=False,
            patience=100,
            # A later stage starts from trained weights: its warm-up ramps
            # every rate up from zero (AdamW's fresh moments with the full rate
            # at once, or the default bias rate of 0.1, knock them back by
            # more than an epoch's progress). A fresh head takes the default.
            warmup_epochs=1.0,
            warmup_bias_lr=0.0 if init and not fresh_head else 0.1,
            close_mosaic=3 if init else 2,
            mosaic=1.0,
            scale=0.5,
            fliplr=0.5,
            verbose=True,
        )
    if not best.exists():
        print(f"error: no {best} after phase {name}", file=sys.stderr)
        return None
    done_marker.write_text("ok\n")
    return best


def main() -> int:
    args = parse_args()
    on_gpu = args.device != "cpu"
    if args.batch is None:
        args.batch = 64 if on_gpu else 8
    if args.workers is None:
        args.workers = max(2, (os.cpu_count() or 4) - 2) if on_gpu else 2
    out = args.out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    # Keep Ultralytics' settings inside the run and never reach the network.
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

    init = resolve_init(args.init, out)
    fresh_head = init is not None and init.name == COCO_INIT_NAME
    started = time.time()
    phases = []
    if args.freeze > 0:
        # The COCO features stay as they are while the new head and the neck
        # learn towers; then every layer trains.
        phases.append(("frozen", args.freeze, args.hours * args.frozen_share))
    phases.append(("train", 0, args.hours * (1 - args.frozen_share) if phases else args.hours))
    for name, freeze, hours in phases:
        weights = run_phase(args, out, name, init, freeze, hours, fresh_head, torch, YOLO, data_yaml)
        if weights is None:
            return 1
        # The next phase starts where this one ended, its head no longer fresh.
        init, fresh_head = weights, False
    run_dir = out / "train"
    best = run_dir / "weights" / "best.pt"
    train_s = time.time() - started

    if not best.exists():
        print(f"error: no {best} after training", file=sys.stderr)
        return 1
    model = YOLO(str(best))
    onnx_path = Path(
        model.export(
            format="onnx",
            opset=17,
            imgsz=(args.export_h, args.export_w),
            simplify=True,
            dynamic=False,
            half=False,
            device="cpu",
        )
    )
    exported = out / "towers.onnx"
    shutil.copyfile(onnx_path, exported)

    metrics = {}
    import yaml

    splits = yaml.safe_load(data_yaml.read_text(encoding="utf-8"))
    for split in ("val", "test"):
        if not splits.get(split):
            continue
        r = model.val(
            data=str(data_yaml),
            split=split,
            imgsz=args.imgsz,
            batch=args.batch,
            device=args.device,
            plots=False,
            project=str(out),
            name=f"val-{split}",
            exist_ok=True,
        )
        metrics[split] = {
            "precision": float(r.box.mp),
            "recall": float(r.box.mr),
            "map50": float(r.box.map50),
            "map50_95": float(r.box.map),
            "per_class_map50_95": {model.names[int(c)]: float(m) for c, m in zip(r.box.ap_class_index, r.box.maps[r.box.ap_class_index])},
        }
    summary = {
        "model": args.model,
        "init": str(args.init) if args.init else None,
        "imgsz": args.imgsz,
        "export_input": [args.export_h, args.export_w],
        "classes": model.names,
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

#!/usr/bin/env python3
"""Mix labelled image sets into one Ultralytics dataset for fine-tuning.

The detector learns real towers from a few real labels and many rendered
ones, and a user's survey labels beside the simulator's frames. Each source is
either a `data.yaml` (the simulator's dataset, `towernav-edge label`'s output,
any Ultralytics dataset) or a folder with `images/` and `labels/` (or
`labels_yolo/`, as the real folders beside the project keep them), whose
class names come from --source-names.

Every source's classes are renamed into --names: the same name, else a
`--map src=dst` rule (`dst` `-` drops the class, and with it every image that
has such a box, so a wooden pole is neither taught as a tower nor as
background), else, for a one-class model, that class. An image with a box of
a class that cannot be named is left out, and counted.

Splits: a source's own val/test splits are kept; a source whose val split is
its train split (a survey flight's labels) holds out its last --hold-out share
of frames in name order, one contiguous stretch of flight, so near-duplicate
neighbours never straddle the split. Held-out frames are also staged as
`heldout/<source>/{images,labels}` for `towernav-edge eval-detector --images`.

Nothing is copied: images are symbolic links, and only label files (renamed
classes) are written, under --out.

    mix.py --out target/train/mixed --names A,B,C,D \\
        --source target/train/dataset/data.yaml \\
        --source ../shared/real/norway_uav --source-names tower_lattice,tower_tucohy,tower_wooden \\
        --map tower_lattice=A --map tower_tucohy=B --map tower_wooden=- --repeat auto
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
from pathlib import Path

IMAGE_SUFFIXES = {".jpg", ".jpeg", ".png", ".bmp", ".webp"}


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, required=True)
    p.add_argument(
        "--names",
        help="the model's class names, comma-separated (default: those of the first data.yaml after the "
        "first source, else the first source's)",
    )
    p.add_argument("--source", action="append", type=Path, required=True, help="data.yaml or labelled folder")
    p.add_argument(
        "--source-names",
        help="class names of folders without data.yaml, comma-separated by class id",
    )
    p.add_argument("--map", action="append", default=[], help="SRC=DST: rename a source class (DST '-' drops it)")
    p.add_argument(
        "--repeat",
        default="auto",
        help="how often each non-first source's training images are listed: a number, or "
        "'auto' (together a third of the training list)",
    )
    p.add_argument("--hold-out", type=float, default=0.2, help="share of a single-split source's frames held out")
    return p.parse_args(argv)


def load_yaml(path: Path) -> dict:
    import yaml

    if not path.is_file():
        raise SystemExit(f"error: {path}: no such file")
    with open(path, encoding="utf-8") as f:
        data = yaml.safe_load(f)
    if not isinstance(data, dict):
        raise SystemExit(f"error: {path}: not a YAML mapping")
    return data


def names_of(data: dict, where: Path) -> list[str]:
    names = data.get("names")
    if isinstance(names, dict):
        return [str(names[k]) for k in sorted(names)]
    if isinstance(names, list):
        return [str(n) for n in names]
    raise SystemExit(f"error: {where}: no `names` list")


def images_in(folder: Path) -> list[Path]:
    if not folder.is_dir():
        raise SystemExit(f"error: {folder}: no such image folder")
    return sorted(p for p in folder.rglob("*") if p.suffix.lower() in IMAGE_SUFFIXES)


def label_for(image: Path) -> Path:
    """Ultralytics' rule: the last `images` directory becomes `labels`; a real
    folder's `labels_yolo` is taken where no `labels` exists."""
    parts = list(image.parts)
    idx = len(parts) - 1 - parts[::-1].index("images")
    stem = Path(*parts[idx + 1 :]).with_suffix(".txt")
    root = Path(*parts[:idx])
    for labels in ("labels", "labels_yolo"):
        if (root / labels).is_dir():
            return root / labels / stem
    return root / "labels" / stem


class Source:
    """One source's splits (image lists) and class names."""

    def __init__(self, path: Path, folder_names: list[str] | None, hold_out: float):
        self.path = path
        if path.suffix in (".yaml", ".yml"):
            data = load_yaml(path)
            base = Path(data.get("path") or path.parent)
            if not base.is_absolute():
                base = (path.parent / base).resolve()
            self.names = names_of(data, path)
            split_dirs = {}
            for split in ("train", "val", "test"):
                value = data.get(split)
                if value is None:
                    continue
                dirs = value if isinstance(value, list) else [value]
                split_dirs[split] = [(base / d).resolve() for d in dirs]
            if "train" not in split_dirs:
                raise SystemExit(f"error: {path}: no `train` split")
            self.splits = {s: [i for d in ds for i in images_in(d)] for s, ds in split_dirs.items()}
            self.shared_val = split_dirs.get("val") == split_dirs["train"] or "val" not in split_dirs
        else:
            if folder_names is None:
                raise SystemExit(f"error: {path} has no data.yaml: give its classes with --source-names")
            self.names = folder_names
            self.splits = {"train": images_in(path / "images")}
            self.shared_val = None  # a folder without splits trains whole
        if self.shared_val:
            frames = self.splits["train"]
            cut = len(frames) - max(1, round(len(frames) * hold_out)) if len(frames) > 1 else len(frames)
            self.splits = {"train": frames[:cut], "val": frames[cut:], "test": frames[cut:]}
        self.held_out = bool(self.shared_val)


def read_boxes(label: Path) -> list[tuple[int, list[str]]]:
    if not label.exists():
        return []
    boxes = []
    for n, line in enumerate(label.read_text(encoding="utf-8").splitlines(), start=1):
        fields = line.split()
        if not fields:
            continue
        if len(fields) != 5:
            raise SystemExit(f"error: {label}:{n}: expected `class cx cy w h`, got {line!r}")
        try:
            cls = int(fields[0])
        except ValueError:
            raise SystemExit(f"error: {label}:{n}: class {fields[0]!r} is not a whole number") from None
        boxes.append((cls, fields[1:]))
    return boxes


def rename_rule(names: list[str], rules: dict[str, str]):
    """A source class name to an output class id, None to drop the image, or
    the string "-" to drop the box's image as well (both mean: leave it out)."""

    def rename(name: str):
        if name in names:
            return names.index(name)
        if name in rules:
            dst = rules[name]
            if dst == "-":
                return None
            if dst not in names:
                raise SystemExit(f"error: --map {name}={dst}: {dst} is not one of the model's classes {names}")
            return names.index(dst)
        if len(names) == 1:
            return 0
        return None

    return rename


def stage(source_index: int, source: Source, split: str, images: list[Path], out: Path, rename, report: dict):
    """Links each image and writes its renamed labels; returns the staged image paths kept."""
    root = out / "stage" / f"{source_index}-{split}"
    kept = []
    for image in images:
        boxes = read_boxes(label_for(image))
        renamed = []
        skip = False
        for cls, rest in boxes:
            if not 0 <= cls < len(source.names):
                raise SystemExit(f"error: {label_for(image)}: class {cls} is outside {source.path}'s {len(source.names)} names")
            dst = rename(source.names[cls])
            if dst is None:
                skip = True
                report["dropped_classes"][source.names[cls]] = report["dropped_classes"].get(source.names[cls], 0) + 1
                break
            renamed.append(f"{dst} {' '.join(rest)}")
        if skip:
            report["images_left_out"] += 1
            continue
        name = f"{len(kept):06d}-{image.name}"
        link = root / "images" / name
        link.parent.mkdir(parents=True, exist_ok=True)
        os.symlink(image.resolve(), link)
        label = root / "labels" / Path(name).with_suffix(".txt")
        label.parent.mkdir(parents=True, exist_ok=True)
        label.write_text("".join(line + "\n" for line in renamed), encoding="utf-8")
        report["boxes"] += len(renamed)
        kept.append(link)
    return kept


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    rules = {}
    for rule in args.map:
        src, sep, dst = rule.partition("=")
        if not sep or not src or not dst:
            raise SystemExit(f"error: --map {rule!r}: expected SRC=DST")
        rules[src] = dst
    folder_names = args.source_names.split(",") if args.source_names else None
    sources = [Source(p, folder_names, args.hold_out) for p in args.source]
    if args.names:
        names = args.names.split(",")
    else:
        # Their classes win: a model fine-tuned on a user's labels names what
        # they named, and the rendered frames mixed in are renamed to fit.
        theirs = [s for s in sources[1:] if s.path.suffix in (".yaml", ".yml")]
        names = (theirs[0] if theirs else sources[0]).names
    out = args.out.resolve()
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)

    lists = {"train": [], "val": [], "test": []}
    reports = []
    staged_train = []
    for k, source in enumerate(sources):
        report = {"source": str(source.path), "names": source.names, "dropped_classes": {}, "images_left_out": 0, "boxes": 0}
        rename = rename_rule(names, rules)
        per_split = {}
        for split, images in source.splits.items():
            per_split[split] = stage(k, source, split, images, out, rename, report)
            report[f"{split}_images"] = len(per_split[split])
        if source.held_out:
            held = out / "heldout" / f"{k}-{source.path.parent.name if source.path.is_file() else source.path.name}"
            held.parent.mkdir(parents=True, exist_ok=True)
            os.symlink(out / "stage" / f"{k}-val", held)
            report["heldout"] = str(held)
        staged_train.append(per_split.get("train", []))
        lists["val"] += per_split.get("val", [])
        lists["test"] += per_split.get("test", [])
        reports.append(report)

    first = len(staged_train[0])
    others = sum(len(t) for t in staged_train[1:])
    for k, train in enumerate(staged_train):
        if k == 0 or not train:
            repeat = 1
        elif args.repeat == "auto":
            # Together the other sources fill a third of the list: few real
            # frames are seen as often as the many rendered ones.
            repeat = max(1, round(first / 2 / max(others, 1)))
        else:
            repeat = int(args.repeat)
        reports[k]["repeat"] = repeat
        lists["train"] += train * repeat
    if not lists["train"]:
        raise SystemExit("error: no training image left after renaming classes")
    if not lists["val"]:
        lists["val"] = staged_train[0][-max(1, len(staged_train[0]) // 10) :]

    for split, images in lists.items():
        (out / f"{split}.txt").write_text("".join(f"{p}\n" for p in images), encoding="utf-8")
    yaml_names = "".join(f"  {i}: {n}\n" for i, n in enumerate(names))
    test_line = "test: test.txt\n" if lists["test"] else ""
    (out / "data.yaml").write_text(
        f"# Mixed by training/mix.py\npath: {out}\ntrain: train.txt\nval: val.txt\n{test_line}names:\n{yaml_names}",
        encoding="utf-8",
    )
    # Plain lists for the model card's step (no JSON parser needed there).
    (out / "names.txt").write_text(",".join(names) + "\n", encoding="utf-8")
    (out / "heldout.txt").write_text("".join(f"{r['heldout']}\n" for r in reports if "heldout" in r), encoding="utf-8")
    (out / "mix.json").write_text(json.dumps({"names": names, "sources": reports}, indent=2) + "\n", encoding="utf-8")
    for r in reports:
        print(
            f"{r['source']}: train {r.get('train_images', 0)} x{r['repeat']}, val {r.get('val_images', 0)}, "
            f"left out {r['images_left_out']} {r['dropped_classes'] or ''}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())

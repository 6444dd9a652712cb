#!/usr/bin/env python3
"""Rebuild the real-photograph part of the detector's data from its sources.

The project commits no third-party image. `training/data/real-sources.csv` is
the manifest: for each source, the folder that holds its fetched copy (under
--real, `../shared/real` by default), the repository and commit it came from,
its licence, its image and steel-tower counts, and its role:

- `train`: trained on (only with a licence that allows it, checked here);
- `held-out`: whole sources kept out of training and scored;
- `eval-only`: scored as tower-free frames, never trained on (no licence).

It writes, under --out (symbolic links and lists only):

- `sources.txt`: the training folders, for `mix.py --source`;
- `backgrounds/`: the training sources' tower-free frames, for the renderer's
  `--backgrounds` (a frame with no label file, or an empty one);
- `held-out.txt`, `negatives.txt`: the folders to score;
- `real-data.json`: what was found, per source, against the manifest.

A copy whose image count differs from the manifest is an error: the training
set would not be the one the manifest names.

    real_data.py --out target/train/real
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import sys
from pathlib import Path

MANIFEST = Path(__file__).resolve().parent / "data" / "real-sources.csv"
IMAGE_SUFFIXES = {".jpg", ".jpeg", ".png"}
# Licences that allow training a shipped model on the images.
TRAINABLE = {"MIT", "Apache-2.0", "BSD-3-Clause", "BSD-2-Clause", "CC0-1.0", "CC-BY-4.0", "CC-BY-SA-4.0"}
ROLES = {"train", "held-out", "eval-only"}
COLUMNS = ["source", "folder", "repository", "commit", "path", "licence", "images", "steel_towers", "role", "note"]


class DataError(Exception):
    pass


def read_manifest(path: Path) -> list[dict]:
    try:
        with open(path, newline="", encoding="utf-8") as f:
            reader = csv.DictReader(f)
            if reader.fieldnames != COLUMNS:
                raise DataError(f"{path}: columns {reader.fieldnames}, expected {COLUMNS}")
            rows = list(reader)
    except OSError as e:
        raise DataError(f"{path}: {e}") from e
    for n, row in enumerate(rows, start=2):
        where = f"{path}:{n} ({row['source']})"
        if row["role"] not in ROLES:
            raise DataError(f"{where}: role {row['role']!r} is not one of {sorted(ROLES)}")
        if row["role"] == "train" and row["licence"] not in TRAINABLE:
            raise DataError(f"{where}: licence {row['licence']!r} does not allow training; make it held-out or eval-only")
        try:
            row["images"] = int(row["images"])
            row["steel_towers"] = int(row["steel_towers"])
        except ValueError as e:
            raise DataError(f"{where}: images and steel_towers must be whole numbers ({e})") from e
    return rows


def images_under(folder: Path) -> list[Path]:
    return sorted(p for p in folder.rglob("*") if p.suffix.lower() in IMAGE_SUFFIXES and "labels" not in p.parts)


def label_of(folder: Path, image: Path) -> Path:
    return folder / "labels_yolo" / (image.stem + ".txt")


def build(manifest: Path, real: Path, out: Path) -> dict:
    rows = read_manifest(manifest)
    out.mkdir(parents=True, exist_ok=True)
    backgrounds = out / "backgrounds"
    backgrounds.mkdir(exist_ok=True)
    for old in backgrounds.iterdir():
        old.unlink()
    lists = {"train": [], "held-out": [], "eval-only": []}
    report = []
    for row in rows:
        folder = (real / row["folder"]).resolve()
        if not folder.is_dir():
            raise DataError(f"{row['source']}: {folder} not found (fetch {row['repository']} and rebuild the folder)")
        images = images_under(folder)
        if len(images) != row["images"]:
            raise DataError(f"{row['source']}: {len(images)} images in {folder}, the manifest says {row['images']}")
        empty = [i for i in images if not label_of(folder, i).exists() or not label_of(folder, i).read_text().strip()]
        if row["role"] == "train":
            for image in empty:
                link = backgrounds / f"{row['source']}-{image.name}"
                link.symlink_to(image)
        lists[row["role"]].append(str(folder))
        report.append(
            {
                "source": row["source"],
                "role": row["role"],
                "licence": row["licence"],
                "repository": row["repository"],
                "commit": row["commit"] or None,
                "images": len(images),
                "tower_free": len(empty),
                "steel_towers": row["steel_towers"],
            }
        )
    (out / "sources.txt").write_text("".join(f"{p}\n" for p in lists["train"]), encoding="utf-8")
    (out / "held-out.txt").write_text("".join(f"{p}\n" for p in lists["held-out"]), encoding="utf-8")
    (out / "negatives.txt").write_text("".join(f"{p}\n" for p in lists["eval-only"]), encoding="utf-8")
    summary = {"manifest": str(manifest), "real": str(real.resolve()), "sources": report, "backgrounds": len(os.listdir(backgrounds))}
    (out / "real-data.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    return summary


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--manifest", type=Path, default=MANIFEST)
    p.add_argument("--real", type=Path, default=Path("../shared/real"), help="folder holding the fetched copies")
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args(argv)
    try:
        summary = build(args.manifest, args.real, args.out)
    except DataError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    for s in summary["sources"]:
        print(f"{s['source']:>20}: {s['role']:<9} {s['licence']:<12} {s['images']:>4} images, {s['tower_free']:>4} tower-free, {s['steel_towers']} steel towers")
    print(f"{summary['backgrounds']} tower-free training frames in {args.out / 'backgrounds'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

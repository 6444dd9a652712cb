#!/usr/bin/env python3
"""INT8 versions of towernav's two models, with ONNX Runtime's own quantizer.

Run through `cargo xtask quantize` (and at the end of `cargo xtask train`), or:

    .venv-train/bin/python training/quantize.py --detector target/train/run/towers.onnx \
        --frames target/train/dataset/images/train \
        --types target/train/types/tower-types.onnx --crops target/train/types/crops/train

Static QDQ quantization (uint8 activations, int8 weights, per tensor, min/max
calibrated) of the convolutions and the activations between them, so the
tensors stay int8 from one convolution to the next. What turns features into
numbers is kept in float: the detector's box decoding (its last layer past the
cv2/cv3 stems: the 1x1 heads, DFL, the anchor grid, pixels do not fit in 256
levels) and the classifier's Gemm and Softmax. Calibration inputs are made
exactly as the edge makes them: letterboxed frames (area filter, grey 114)
and the classifier's crops. Class names and the rest of the metadata are
copied, so the edge loads an INT8 model as it loads the float one.

The accuracy check is the Rust evaluator on held-out worlds:
`towernav-edge eval-detector --model <int8> --type-model <int8>`.
"""

from __future__ import annotations

import argparse
import json
import random
import re
import sys
import tempfile
import time
from pathlib import Path

QUANTIZED_OPS = ["Conv", "Mul", "Sigmoid", "Add", "Concat", "MaxPool", "Resize", "Split", "GlobalAveragePool"]


def parse_args() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--detector", type=Path, help="float detector export (writes <name>-int8.onnx beside it)")
    p.add_argument("--frames", type=Path, help="training frames to calibrate the detector on")
    p.add_argument("--types", type=Path, help="float type-classifier export (writes <name>-int8.onnx beside it)")
    p.add_argument("--crops", type=Path, help="training crops (class folders) to calibrate the classifier on")
    p.add_argument("--samples", type=int, default=100, help="calibration inputs per model")
    p.add_argument("--seed", type=int, default=0)
    return p.parse_args()


def int8_path(model: Path) -> Path:
    return model.with_name(model.stem + "-int8.onnx")


def sample(files: list[Path], n: int, seed: int) -> list[Path]:
    files = sorted(files)
    random.Random(seed).shuffle(files)
    return files[:n]


def letterbox(path: Path, width: int, height: int):
    """The edge's pre-processing (`detector::Preprocessor`): NCHW float in 0..1."""
    import numpy as np
    from PIL import Image

    image = Image.open(path).convert("RGB")
    scale = min(width / image.width, height / image.height)
    w, h = round(image.width * scale), round(image.height * scale)
    canvas = Image.new("RGB", (width, height), (114, 114, 114))
    canvas.paste(image.resize((w, h), Image.BOX), ((width - w) // 2, (height - h) // 2))
    return (np.asarray(canvas, dtype=np.float32) / 255.0).transpose(2, 0, 1)[None]


def crop_input(path: Path, size: int):
    import numpy as np
    from PIL import Image

    image = Image.open(path).convert("RGB").resize((size, size), Image.BILINEAR)
    return (np.asarray(image, dtype=np.float32) / 255.0).transpose(2, 0, 1)[None]


def float_head(model, kind: str) -> list[str]:
    """Nodes kept in float: the detector's decoding, the classifier's head."""
    nodes = list(model.graph.node)
    if kind == "classifier":
        return [n.name for n in nodes if n.op_type in ("Gemm", "Softmax", "Flatten")]
    layers = [int(m.group(1)) for n in nodes if (m := re.match(r"/model\.(\d+)/", n.name))]
    if not layers:
        raise SystemExit("the detector's nodes are not named /model.<layer>/...: not an Ultralytics export")
    head = f"/model.{max(layers)}/"
    stem = re.compile(r"cv[23]\.\d+\.[01]/")
    return [n.name for n in nodes if n.name.startswith(head) and not stem.search(n.name)]


def quantize(src: Path, inputs, kind: str) -> dict:
    import onnx
    from onnxruntime.quantization import CalibrationDataReader, QuantFormat, QuantType, quantize_static
    from onnxruntime.quantization.shape_inference import quant_pre_process

    dst = int8_path(src)
    started = time.time()
    with tempfile.TemporaryDirectory() as tmp:
        prepared = Path(tmp) / "prepared.onnx"
        quant_pre_process(str(src), str(prepared))
        model = onnx.load(str(prepared))
        input_name = model.graph.input[0].name
        keep_float = float_head(model, kind)

        class Reader(CalibrationDataReader):
            def __init__(self):
                self.items = iter(inputs)

            def get_next(self):
                item = next(self.items, None)
                return None if item is None else {input_name: item()}

        quantize_static(
            str(prepared),
            str(dst),
            Reader(),
            quant_format=QuantFormat.QDQ,
            per_channel=False,
            activation_type=QuantType.QUInt8,
            weight_type=QuantType.QInt8,
            op_types_to_quantize=QUANTIZED_OPS,
            nodes_to_exclude=keep_float,
        )
    quantized = onnx.load(str(dst))
    del quantized.metadata_props[:]
    quantized.metadata_props.extend(onnx.load(str(src)).metadata_props)
    onnx.save(quantized, str(dst))
    print(f"{dst}: {dst.stat().st_size} bytes ({len(keep_float)} nodes kept in float), {time.time() - started:.0f} s")
    return {"onnx": str(dst), "bytes": dst.stat().st_size, "float_nodes": len(keep_float)}


def input_size(path: Path) -> tuple[int, int]:
    import onnx

    dims = onnx.load(str(path)).graph.input[0].type.tensor_type.shape.dim
    return dims[2].dim_value, dims[3].dim_value


def main() -> int:
    args = parse_args()
    summary = {}
    if args.detector:
        if not args.frames or not args.detector.is_file():
            print(f"error: --detector needs an exported model ({args.detector}) and --frames", file=sys.stderr)
            return 2
        frames = sample([*args.frames.glob("*.jpg"), *args.frames.glob("*.png")], args.samples, args.seed)
        if not frames:
            print(f"error: no .jpg or .png frames in {args.frames}", file=sys.stderr)
            return 2
        h, w = input_size(args.detector)
        summary["detector"] = quantize(args.detector, [lambda f=f: letterbox(f, w, h) for f in frames], "detector")
        summary["detector"]["calibration_frames"] = len(frames)
    if args.types:
        if not args.crops or not args.types.is_file():
            print(f"error: --types needs an exported classifier ({args.types}) and --crops", file=sys.stderr)
            return 2
        crops = sample(list(args.crops.glob("*/*.png")), args.samples, args.seed)
        if not crops:
            print(f"error: no class-folder .png crops in {args.crops}", file=sys.stderr)
            return 2
        size, _ = input_size(args.types)
        summary["types"] = quantize(args.types, [lambda f=f: crop_input(f, size) for f in crops], "classifier")
        summary["types"]["calibration_crops"] = len(crops)
    if not summary:
        print("error: nothing to quantize (give --detector and/or --types)", file=sys.stderr)
        return 2
    print(json.dumps(summary, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env bash
# Reproduces the committed model: renders the training and test sets with citymesh, trains on CPU,
# exports roof_classifier.onnx and writes metrics.json (quoted in MODEL_CARD.md). Run from the
# repository root: training/roof_classifier/train.sh. Takes about four and a half hours on 2 quiet cores.
set -euo pipefail
cd "$(dirname "$0")/../.."
data="${CITYMESH_DATA_DIR:-../shared/data}"
work="${WORK_DIR:-target/roof_classifier}"
osm=("$data/osm/karlsruhe-kirchfeld.osm.pbf" "$data/osm/karlsruhe-kit-nord.osm.pbf"
     "$data/osm/nuremberg-laufamholz.osm" "$data/osm/san-francisco.overpass.json.gz")
for f in "${osm[@]}"; do [ -f "$f" ] || { echo "error: $f missing (set CITYMESH_DATA_DIR)" >&2; exit 1; }; done

venv=.venv-train
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
  "$venv/bin/pip" install -q -r training/roof_classifier/requirements.txt
fi
cargo build --release --bin citymesh
bin=target/release/citymesh
rm -rf "$work" && mkdir -p "$work"
"$bin" render-roofs "${osm[@]/#/--osm=}" --procedural 1,2,3,4 --count 36000 --seed 1 \
  --palette training -o "$work/train"
"$bin" render-roofs "${osm[@]/#/--osm=}" --procedural 11,12 --count 3000 --seed 2 \
  --palette holdout -o "$work/test"
"$bin" render-roofs "${osm[@]/#/--osm=}" --procedural 1,2,3,4 --count 108000 --seed 1 \
  --palette training -o "$work/train108"
"$bin" render-roofs "${osm[@]/#/--osm=}" --procedural 7,8,9,10 --count 108000 --seed 4 \
  --palette training -o "$work/train108b"
recipe=(--symmetry rect --spatial --deep --width 16,32,64,192)
# Stage 1: 30 epochs on the first 36,000 crops.
"$venv/bin/python" training/roof_classifier/train.py --train "$work/train" --test "$work/test" \
  --out "$work/stage1.onnx" --metrics "$work/stage1.json" "${recipe[@]}" --epochs 30
# Stage 2: 8 more epochs from there on 108,000 crops (the first 36,000 are stage 1's), half of
# them with their hue turned.
"$venv/bin/python" training/roof_classifier/train.py --train "$work/train108" --test "$work/test" \
  --out "$work/stage2.onnx" --metrics "$work/stage2.json" \
  "${recipe[@]}" --init "$work/stage1.pt" --hue 0.5 --lr 1.5e-3 --epochs 8
# Stage 3: a residual convolution added at 8 x 8 (starting as the identity), 10 more epochs.
"$venv/bin/python" training/roof_classifier/train.py --train "$work/train108" --test "$work/test" \
  --out "$work/stage3.onnx" --metrics "$work/stage3.json" \
  "${recipe[@]}" --residual 1 --init "$work/stage2.pt" --hue 0.5 --lr 1.5e-3 --epochs 10 \
  --seed 20261128
# Stage 4: 5 more epochs at a lower learning rate.
"$venv/bin/python" training/roof_classifier/train.py --train "$work/train108" --test "$work/test" \
  --out "$work/stage4.onnx" --metrics "$work/stage4.json" \
  "${recipe[@]}" --residual 1 --init "$work/stage3.pt" --hue 0.5 --lr 7e-4 --epochs 5 \
  --seed 20261129
# Stage 5: 7 epochs on both 108,000-crop sets (216,000 crops), with stronger colour changes
# (channel gains up to 15 %, a random gamma).
"$venv/bin/python" training/roof_classifier/train.py --train "$work/train108" --train "$work/train108b" \
  --test "$work/test" --out training/roof_classifier/roof_classifier.onnx --metrics "$work/training.json" \
  "${recipe[@]}" --residual 1 --init "$work/stage4.pt" --hue 0.5 --gain 0.15 --gamma 0.3 --lr 1e-3 \
  --epochs 7 --seed 20261130
# Accuracy as citymesh runs the model (ONNX Runtime, averaged over the rectangle's turns and
# flips for crops with a footprint, all 8 for crops without, each at 5 shifts).
(cd training/roof_classifier && "../../$venv/bin/python" evaluate.py roof_classifier.onnx \
  "../../$work/test" metrics.json rect shift)
sha256sum training/roof_classifier/roof_classifier.onnx

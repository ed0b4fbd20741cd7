#!/usr/bin/env bash
# Reproduces the committed model: renders the training and test sets with citymesh, trains on CPU,
# exports roof_classifier.onnx and writes metrics.json (quoted in MODEL_CARD.md). Run from the
# repository root: training/roof_classifier/train.sh. Takes about an hour on 2 quiet cores.
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
"$venv/bin/python" training/roof_classifier/train.py --train "$work/train" --test "$work/test" \
  --out training/roof_classifier/roof_classifier.onnx --metrics "$work/training.json" \
  --symmetry rect --spatial --deep --width 16,32,64,192 --epochs 30
# Accuracy as citymesh runs the model (ONNX Runtime, averaged over the rectangle's turns and
# flips for crops with a footprint, all 8 for crops without).
(cd training/roof_classifier && "../../$venv/bin/python" evaluate.py roof_classifier.onnx \
  "../../$work/test" metrics.json rect)
sha256sum training/roof_classifier/roof_classifier.onnx

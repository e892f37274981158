#!/usr/bin/env bash
# Regenerates lab/assets/fonts/DejaVuSans-subset.ttf, the font the experiment plots are drawn
# with (compiled into the binary, so a machine without fonts draws the same PNGs): DejaVu
# Sans (Debian's fonts-dejavu-core) cut to printable ASCII and the few symbols the plots use.
set -euo pipefail
cd "$(dirname "$0")/.."
venv=$(mktemp -d)
python3 -m venv "$venv"
"$venv/bin/pip" install --quiet fonttools==4.68.0
"$venv/bin/pyftsubset" /usr/share/fonts/truetype/dejavu/DejaVuSans.ttf \
  --unicodes="U+0020-007E,U+00B2,U+00B7,U+00D7,U+0394,U+03B8,U+2016,U+2013,U+2014,U+2212,U+2264,U+2265,U+2080-2089,U+0302" \
  --layout-features='' --no-hinting --desubroutinize \
  --output-file=assets/fonts/DejaVuSans-subset.ttf
rm -rf "$venv"

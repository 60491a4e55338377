#!/usr/bin/env bash
# Runs the cargo-fuzz targets for SECONDS each: all of them, or those named.
#   bash scripts/fuzz.sh 600                       # every target, 10 minutes each
#   bash scripts/fuzz.sh 30 ply_file xyz_file      # two targets, 30 s each
# Installs cargo-fuzz when missing and seeds each target's corpus (fuzz/corpus/TARGET) from
# testdata/ and small generated PLY, text and store files. Findings land in fuzz/artifacts/;
# the exit status is non-zero when any target found one.
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:?usage: scripts/fuzz.sh SECONDS [TARGET...]}
shift
command -v cargo-fuzz >/dev/null || cargo install cargo-fuzz --locked
# cargo-fuzz needs nightly flags (sanitizers); a stable toolchain allows them with
# RUSTC_BOOTSTRAP, set for cargo fuzz alone (elsewhere it would rebuild the workspace).
fuzz() { RUSTC_BOOTSTRAP=1 cargo fuzz "$@"; }

targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
    mapfile -t targets < <(fuzz list)
fi

corpus=fuzz/corpus
seed() { mkdir -p "$corpus/$1"; }

seed las_header
seed las_file
for f in testdata/*.las testdata/*.laz; do
    name=$(basename "$f")
    head -c 4096 "$f" > "$corpus/las_header/$name"
    # Whole files only when small: libFuzzer's input length follows the largest seed.
    if [ "$(stat -c %s "$f")" -le 70000 ]; then cp "$f" "$corpus/las_file/$name"; fi
done

# parted_file: the same files, and generated ones with more points than a decoding block
# (1,024 LAZ records, 2,048 LAS records), so that the fuzzer meets the blocks' seams.
seed parted_file
cp "$corpus"/las_file/* "$corpus/parted_file/"
for f in blocks.las:2100 blocks.laz:3000; do
    if [ ! -e "$corpus/parted_file/${f%%:*}" ]; then
        cargo run --quiet -p pointlet -- generate --points "${f##*:}" \
            -o "$corpus/parted_file/${f%%:*}" 2>/dev/null
    fi
done

# laz_chunk: a selector byte (0x13: format 3, 1 + 97 points claimed), then the first chunk of
# simple.laz, 8 bytes after the point data offset (a u32 at header byte 96).
seed laz_chunk
at=$(od -An -tu4 -j96 -N4 testdata/simple.laz | tr -d ' ')
# (dd, not tail | head: head's early exit would kill tail with SIGPIPE, fatal under pipefail.)
{ printf '\x13'; dd if=testdata/simple.laz iflag=skip_bytes,count_bytes skip=$((at + 8)) count=8192 status=none; } > "$corpus/laz_chunk/simple"

seed store_reader
if [ ! -e "$corpus/store_reader/generated.pointlet" ]; then
    cargo run --quiet -p pointlet -- generate --points 300 --pointlets 2 \
        -o "$corpus/store_reader/generated.pointlet" 2>/dev/null
    cargo run --quiet -p pointlet -- convert testdata/simple.las --pointlets 4 \
        -o "$corpus/store_reader/simple.pointlet" 2>/dev/null
fi

seed ply_file
vertex_header() { # FORMAT COUNT
    printf 'ply\nformat %s 1.0\ncomment seed\nelement camera 1\nproperty list uchar int ids\n' "$1"
    printf 'element vertex %s\nproperty float x\nproperty double y\nproperty int z\n' "$2"
    printf 'property uchar red\nproperty uchar green\nproperty uchar blue\nproperty float intensity\n'
    printf 'property list uchar float extra\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n'
}
{ vertex_header ascii 2; printf '2 1 2\n1.5 2.25 3 255 0 10 0.5 0\n4 5 -6 1 2 3 1 2 0.1 0.2\n3 0 1 1\n'; } \
    > "$corpus/ply_file/ascii.ply"
# x = 1.0f, y = 2.0, z = 3, rgb 1 2 3, intensity 0.5f, an empty list; the faces' list.
{ vertex_header binary_little_endian 1
  printf '\x01\x07\x00\x00\x00'
  printf '\x00\x00\x80\x3f\x00\x00\x00\x00\x00\x00\x00\x40\x03\x00\x00\x00\x01\x02\x03\x00\x00\x00\x3f\x00'
  printf '\x01\x00\x00\x00\x00'; } > "$corpus/ply_file/le.ply"
{ vertex_header binary_big_endian 1
  printf '\x01\x00\x00\x00\x07'
  printf '\x3f\x80\x00\x00\x40\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x03\x01\x02\x03\x3f\x00\x00\x00\x00'
  printf '\x01\x00\x00\x00\x00'; } > "$corpus/ply_file/be.ply"

seed xyz_file
printf '1 2 3\n4.5 5 -6\n' > "$corpus/xyz_file/plain.xyz"
printf '# comment\n1;2;3;100\n4;5;6;200\n' > "$corpus/xyz_file/intensity.txt"
printf '1 2 3 0 128 255\n4 5 6 10 20 30\n' > "$corpus/xyz_file/rgb.xyz"
printf '2\n1 2 3 -2048 10 20 30\n4 5 6 2047 40 50 60\n' > "$corpus/xyz_file/count.pts"
printf 'X,Y,Z,Class,Return_Number,Number_Of_Returns,GPS_Time,NIR,nx\n1,2,3,2,1,2,10.5,300,0.1\n' \
    > "$corpus/xyz_file/named.csv"
printf '//X,Y,Z,Rf,Gf,Bf,Intensity\n1.5,2,3,1,0.5,0,200\n' > "$corpus/xyz_file/cloudcompare.txt"
printf '@x,y,z,r,g,b,intensity\n1 2 3 255 128 0 100\n4 5 6 0 10 20 30000\n' \
    > "$corpus/xyz_file/columns.xyz"

seed pnts
cp testdata/tiles/autzen_pnts/points/r3.pnts testdata/tiles/simple_pnts/points/r7.pnts \
    "$corpus/pnts/"
cp testdata/tiles/autzen_glb/points/r3.glb "$corpus/pnts/r3.glb"

failed=()
for t in "${targets[@]}"; do
    echo "== $t: ${secs} s"
    if ! fuzz run "$t" -- -max_total_time="$secs" -timeout=30; then
        failed+=("$t")
    fi
done
if [ ${#failed[@]} -gt 0 ]; then
    echo "findings (see fuzz/artifacts/): ${failed[*]}" >&2
    exit 1
fi
echo "no findings in ${targets[*]} (${secs} s each)"

#!/usr/bin/env bash
# Builds scripts/pinocchio_cpp/bench.cpp, the Pinocchio C++ API benchmark (see README.md here),
# against the Pinocchio of a Python venv that has the `pin` wheel (Pinocchio 4.x): its headers
# and shared libraries live under site-packages/cmeel.prefix/. The wheel ships neither the
# Eigen headers nor urdfdom's headers, so the pinned cmeel header packages below are
# pip-installed into that venv first if they are missing (Boost's come with `pin`, through
# cmeel-boost). No cmake: the flags below are those of Pinocchio's exported cmake targets
# (lib/cmake/pinocchio/pinocchioTargets.cmake, target pinocchio::pinocchio), written out.
#
#   scripts/pinocchio_cpp/build.sh [PYTHON_VENV_DIR (default .venv)] [OUT (default target/pinocchio-bench/bench)]
#
# Builds two binaries (~4 min and ~20 s of one core), alike but for where Pinocchio's algorithms
# are compiled (bench.cpp's header says more):
#   OUT      all of Pinocchio's templates instantiated in bench.cpp, -O3 -march=native;
#   OUT-lib  aba/rnea/crba/computeABADerivatives from libpinocchio_default.so's explicit
#            instantiations (PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION, as the cmake target sets
#            it), i.e. the wheel's generic x86-64 build, the code the Python binding runs.
# Run from the repository root. The binary finds the libraries through an rpath to the venv's
# cmeel.prefix/lib (no LD_LIBRARY_PATH needed), so it breaks if the venv moves.
#
# -DEIGEN_MAX_ALIGN_BYTES=16 -DEIGEN_MALLOC_ALREADY_ALIGNED=1 are required, not tuning: the
# wheel's libraries are built for generic x86-64 (SSE2: Eigen aligns to 16 bytes and allocates
# with plain malloc/free), and they share pinocchio::Model / Data with this binary (the URDF
# parser builds the Model). -march=native on an AVX/AVX-512 machine would otherwise (1) raise
# Eigen's static alignment to 32/64 bytes, changing the layout of Data (6816 bytes instead of
# 6800 here), and (2) even with EIGEN_MAX_ALIGN_BYTES=16, keep EIGEN_DEFAULT_ALIGN_BYTES at 64
# (Eigen 3.4 takes the larger of the ideal and the maximum) and so switch Eigen's heap
# allocator to its handmade offset-pointer one: freeing in this binary a vector the library
# allocated then crashes (seen: SIGSEGV in ~Model after urdf::buildModel).
set -euo pipefail

venv=${1:-.venv}
out=${2:-target/pinocchio-bench/bench}
src=scripts/pinocchio_cpp/bench.cpp

# Pinned: the versions pip picked for Pinocchio 4.1.0 (pin / libpinocchio 4.1.0, cmeel-boost
# 1.90.0). libpinocchio's cmake config records urdfdom_headers 3.0.0.
pins=(cmeel-eigen==3.4.1 cmeel-urdfdom-headers==3.0.0 cmeel-boost==1.90.0)

py="$venv/bin/python"
[ -x "$py" ] || { echo "no python at $py" >&2; exit 1; }
[ -f "$src" ] || { echo "run from the repository root ($src not found)" >&2; exit 1; }
site=$("$py" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
prefix="$site/cmeel.prefix"
[ -f "$prefix/lib/libpinocchio_default.so" ] \
  || { echo "no libpinocchio_default.so under $prefix: pip install pin into $venv" >&2; exit 1; }

missing=()
for pin in "${pins[@]}"; do
  name=${pin%%==*} want=${pin#*==}
  # `pip show` fails on a package that is not there, which is what this loop looks for.
  have=$("$py" -m pip show "$name" 2>/dev/null | sed -n 's/^Version: //p' || true)
  [ "$have" = "$want" ] || missing+=("$pin")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "pip install ${missing[*]} into $venv" >&2
  "$py" -m pip install --quiet "${missing[@]}"
fi

lib="$(cd "$prefix/lib" && pwd -P)"
inc="$prefix/include"
defs=(
  # pinocchio::pinocchio_headers
  -DBOOST_MPL_LIMIT_LIST_SIZE=30 -DBOOST_MPL_LIMIT_VECTOR_SIZE=30
  -DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS -DBOOST_FUSION_INVOKE_MAX_ARITY=12
  # pinocchio_default / pinocchio_collision / pinocchio_parsers (and, for OUT-lib only,
  # PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION: below)
  -DPINOCCHIO_WITH_COLLISION -DPINOCCHIO_WITH_HPP_FCL
  -DPINOCCHIO_WITH_URDFDOM -DPINOCCHIO_URDFDOM_HEADERS_MAJOR_VERSION=3
  -DPINOCCHIO_URDFDOM_HEADERS_MINOR_VERSION=0 -DPINOCCHIO_URDFDOM_HEADERS_PATCH_VERSION=0
  # coal::coal
  -DCOAL_BACKWARD_COMPATIBILITY_WITH_HPP_FCL -DCOAL_HAS_OCTOMAP -DCOAL_HAVE_OCTOMAP
  -DOCTOMAP_MAJOR_VERSION=1 -DOCTOMAP_MINOR_VERSION=10 -DOCTOMAP_PATCH_VERSION=0
  # ABI with the wheel's libraries: see the header
  -DEIGEN_MAX_ALIGN_BYTES=16 -DEIGEN_MALLOC_ALREADY_ALIGNED=1
)
incs=(
  -isystem "$inc" -isystem "$inc/pinocchio/deprecated" -isystem "$inc/eigen3"
  -isystem "$inc/urdfdom_headers" -isystem "$inc/urdfdom"
)
libs=(-lpinocchio_parsers -lpinocchio_default -lurdfdom_model -lboost_filesystem -lboost_serialization)

mkdir -p "$(dirname "$out")"
# -Wno-stringop-overread: GCC 12 false positives inside Eigen's AVX-512 packet code (dead
# branches on 6-vectors); the warning is on by default.
build() { # OUTPUT [EXTRA_FLAGS...]
  local o=$1
  shift
  local cmd=(g++ -std=c++17 -O3 -march=native -DNDEBUG -Wno-stringop-overread "$@" "${defs[@]}"
    "${incs[@]}" "$src" -o "$o" -L"$lib" -Wl,-rpath,"$lib" -Wl,--as-needed "${libs[@]}")
  echo "${cmd[*]}" >&2
  "${cmd[@]}"
  echo "built $o" >&2
}
build "$out"
build "$out-lib" -DBENCH_USE_LIBRARY -DPINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION

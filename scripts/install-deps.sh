#!/usr/bin/env bash
# Installs everything qdrun needs from Debian 12's repositories. Idempotent; fast when already done.
#   scripts/install-deps.sh          build and test dependencies
#   scripts/install-deps.sh --mpi    also OpenMPI (for -DQD_WITH_MPI=ON)
#   scripts/install-deps.sh --plots  also matplotlib for the system Python (share/qd/qdplot)
set -euo pipefail
packages=(cmake g++ ninja-build pkg-config libeigen3-dev libbox2d-dev libboost-dev libboost-program-options-dev
          libtomlplusplus-dev libgtest-dev)
for arg in "$@"; do
  case $arg in
    --mpi) packages+=(libopenmpi-dev openmpi-bin) ;;
    --plots) packages+=(python3-matplotlib python3-numpy) ;;
    *) echo "unknown option $arg" >&2; exit 2 ;;
  esac
done
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi
sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo"
echo "install-deps: installing ${missing[*]}"
$sudo apt-get update -qq
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" > /dev/null

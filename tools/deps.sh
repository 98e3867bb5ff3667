#!/usr/bin/env bash
# Installs what sandcell needs to build, test and plot, from Debian 12 packages; does nothing when
# everything is already there (idempotent). Uses sudo when not run as root.
set -euo pipefail
packages=(build-essential cmake ninja-build libeigen3-dev libtbb-dev libhdf5-dev doctest-dev
          libtomlplusplus-dev libcli11-dev
          python3-h5py python3-matplotlib python3-numpy python3-scipy python3-pytest flake8
          pybind11-dev python3-dev
          slurm-wlm munge)  # slurm-wlm, munge: the cluster test starts a real single-node Slurm
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "deps: all ${#packages[@]} packages present"
  exit 0
fi
echo "deps: installing ${missing[*]}"
sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo"
$sudo apt-get update -qq
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"

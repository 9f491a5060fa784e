# Sourced by the scripts of bench/device: the repository root as working directory, the
# build folder, the CLI and the data copies every device call carries in .devdata
# (copies of ../shared/data: CMU Panoptic basketball, 30 timesteps; the tiny D-NeRF lego).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
BUILD=${ATEX_GPU_BUILD:-bg}  # git-ignored: on a lent machine only ignored folders persist between calls
atex=$BUILD/bin/atex
bb=.devdata/panoptic_basketball
lego=.devdata/dnerf_lego_tiny/tiny_dnerf_data.npz
mkdir -p out

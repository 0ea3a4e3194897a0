#!/usr/bin/env bash
# voxlab's test command: sets up what a fresh Debian machine lacks, then runs every test.
#
#   bash tests/run.sh            (as root on Debian, or with sudo available)
#
# GPU tests need a Vulkan adapter. On a machine without a GPU, Mesa's software driver
# lavapipe (Debian package mesa-vulkan-drivers) is one; it is installed here when no
# Vulkan driver is present. A missing adapter then fails the GPU tests: never a skip.
set -euo pipefail
cd "$(dirname "$0")/.."

have_vulkan_driver() {
    compgen -G "/usr/share/vulkan/icd.d/*.json" >/dev/null ||
        compgen -G "/etc/vulkan/icd.d/*.json" >/dev/null
}

if ! have_vulkan_driver || ! ldconfig -p | grep -q 'libvulkan\.so\.1'; then
    echo "tests/run.sh: no Vulkan driver found; installing mesa-vulkan-drivers (lavapipe)"
    sudo=""
    if [ "$(id -u)" -ne 0 ]; then
        command -v sudo >/dev/null || { echo "tests/run.sh: need root or sudo to install mesa-vulkan-drivers" >&2; exit 1; }
        sudo=sudo
    fi
    export DEBIAN_FRONTEND=noninteractive
    $sudo apt-get update -qq
    $sudo apt-get install -y -qq --no-install-recommends mesa-vulkan-drivers libvulkan1 >/dev/null
    have_vulkan_driver || { echo "tests/run.sh: mesa-vulkan-drivers installed no Vulkan driver" >&2; exit 1; }
fi

if ! command -v cargo >/dev/null; then
    echo "tests/run.sh: cargo not found; install the Rust toolchain (https://rustup.rs) first" >&2
    exit 1
fi

# Release mode: the f64 reference renders real images in the tests, and the README's
# render command builds the same artifacts.
cargo test --release --locked "$@"

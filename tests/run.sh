#!/usr/bin/env bash
# voxlab's test command: sets up what a fresh Debian machine lacks, then runs every test.
#
#   bash tests/run.sh            (as root on Debian, or with sudo available)
#
# GPU tests need a Vulkan adapter. On a machine without a GPU, Mesa's software driver
# lavapipe (Debian package mesa-vulkan-drivers) is one; it is installed here when no
# Vulkan driver is present. A missing adapter then fails the GPU tests: never a skip.
# The viewer's end-to-end test opens its window on a virtual X server (Xvfb, with the X
# client libraries winit loads at run time); those are installed here too when missing.
set -euo pipefail
cd "$(dirname "$0")/.."

have_vulkan_driver() {
    compgen -G "/usr/share/vulkan/icd.d/*.json" >/dev/null ||
        compgen -G "/etc/vulkan/icd.d/*.json" >/dev/null
}

need=()
if ! have_vulkan_driver || ! ldconfig -p | grep -q 'libvulkan\.so\.1'; then
    echo "tests/run.sh: no Vulkan driver found; installing mesa-vulkan-drivers (lavapipe)"
    need+=(mesa-vulkan-drivers libvulkan1)
fi
# winit opens these with dlopen, so a build succeeds without them and only the window fails.
x11_libs=(libX11.so.6 libX11-xcb.so.1 libXcursor.so.1 libXrandr.so.2 libXi.so.6 libxkbcommon-x11.so.0)
missing_lib=""
for lib in "${x11_libs[@]}"; do
    ldconfig -p | grep -q "$lib" || missing_lib="$lib"
done
if ! command -v Xvfb >/dev/null || [ -n "$missing_lib" ]; then
    echo "tests/run.sh: installing Xvfb and the X client libraries for the viewer's end-to-end test"
    need+=(xvfb libx11-6 libx11-xcb1 libxcursor1 libxrandr2 libxi6 libxkbcommon-x11-0)
fi
# The Python bindings' tests need a venv (Debian splits the venv module out of python3).
if ! command -v python3 >/dev/null || ! python3 -c 'import venv, ensurepip' 2>/dev/null; then
    echo "tests/run.sh: installing python3 and python3-venv for the Python bindings' tests"
    need+=(python3 python3-venv)
fi
if [ ${#need[@]} -gt 0 ]; then
    sudo=""
    if [ "$(id -u)" -ne 0 ]; then
        command -v sudo >/dev/null || { echo "tests/run.sh: need root or sudo to install ${need[*]}" >&2; exit 1; }
        sudo=sudo
    fi
    export DEBIAN_FRONTEND=noninteractive
    $sudo apt-get update -qq
    $sudo apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
    have_vulkan_driver || { echo "tests/run.sh: mesa-vulkan-drivers installed no Vulkan driver" >&2; exit 1; }
    command -v Xvfb >/dev/null || { echo "tests/run.sh: the xvfb package installed no Xvfb" >&2; exit 1; }
fi

if ! command -v cargo >/dev/null; then
    echo "tests/run.sh: cargo not found; install the Rust toolchain (https://rustup.rs) first" >&2
    exit 1
fi

# Mesa's Vulkan drivers probe Wayland and libwayland complains on every device when
# XDG_RUNTIME_DIR is missing (as under CI): a private one keeps the test output readable.
if [ -z "${XDG_RUNTIME_DIR:-}" ] || [ ! -d "${XDG_RUNTIME_DIR}" ]; then
    XDG_RUNTIME_DIR="$(mktemp -d)"
    export XDG_RUNTIME_DIR
fi

# Release mode: the f64 reference renders real images in the tests, and the README's
# render command builds the same artifacts.
cargo test --release --locked "$@"

# The Python package (python/): built into a venv of its own with maturin, then its
# pytest suite (GPU = CPU through Python, numpy round trips, errors, provenance, the
# example notebook). The pinned packages come from PyPI.
venv=target/python-venv
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
"$venv/bin/python" -m pip install -q --disable-pip-version-check -r python/requirements-test.txt
(cd python && VIRTUAL_ENV="$PWD/../$venv" PATH="$PWD/../$venv/bin:$PATH" \
    maturin develop --release --locked -q)
"$venv/bin/python" -m pytest -q python/tests

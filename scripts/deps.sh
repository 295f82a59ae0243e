#!/usr/bin/env bash
# Installs what the build and the tests need, idempotently: Debian packages (only the missing ones)
# and the npm packages of package.json (only when node_modules is out of date).
set -euo pipefail
cd "$(dirname "$0")/.."

APT_PACKAGES=(
  build-essential cmake ninja-build pkg-config clang clang-format libclang-rt-14-dev
  libembree-dev libopenimageio-dev openimageio-tools libqhull-dev
  python3 python3-dev python3-numpy python3-scipy python3-pytest python3-matplotlib
  python3-pytest-xdist  # ./test.sh runs pytest on 2 workers (-n 2 --dist loadfile)
  python3-pip python3-setuptools python3-wheel
  blender
  libvulkan-dev glslc mesa-vulkan-drivers vulkan-validationlayers vulkan-tools
  libcjson-dev libglfw3-dev xvfb xauth
  nodejs npm
  chromium  # tests/web/test_web_page.py: the three.js page in headless Chromium (WebGL2 on SwiftShader)
  debootstrap patchelf
  slurm-wlm munge
)

missing=()
for p in "${APT_PACKAGES[@]}"; do
  # nodejs/npm may come from elsewhere (e.g. a preinstalled Node); accept any working binary.
  case "$p" in
    nodejs) command -v node >/dev/null 2>&1 && continue ;;
    npm) command -v npm >/dev/null 2>&1 && continue ;;
  esac
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if ((${#missing[@]})); then
  echo "deps: installing ${missing[*]}"
  SUDO=""
  if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
  $SUDO apt-get update -q
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q "${missing[@]}"  # with recommends, as tested
fi

# The root's packages (the glTF validator) and web/'s (three.js for the plugin, issue 32).
for dir in . web; do
  if [ -f "$dir/package.json" ]; then
    if [ ! -d "$dir/node_modules" ] || [ "$dir/package.json" -nt "$dir/node_modules" ] || \
       { [ -f "$dir/package-lock.json" ] && [ "$dir/package-lock.json" -nt "$dir/node_modules" ]; }; then
      echo "deps: npm packages in $dir"
      if [ -f "$dir/package-lock.json" ]; then (cd "$dir" && npm ci --no-audit --no-fund --loglevel=error)
      else (cd "$dir" && npm install --no-audit --no-fund --loglevel=error); fi
      touch "$dir/node_modules"
    fi
  fi
done

#!/bin/sh
# Install the system libraries the project needs when they are missing:
# EGL + Mesa (llvmpipe) for headless OpenGL 4.5.
# Only acts when something is missing; needs root (CI runs as root) or sudo.
missing=""
ldconfig -p 2>/dev/null | grep -q 'libEGL.so.1' || missing="$missing libegl1"
ldconfig -p 2>/dev/null | grep -q 'libEGL_mesa.so.0' || missing="$missing libegl-mesa0 libgl1-mesa-dri"
ldconfig -p 2>/dev/null | grep -q 'libGL.so.1' || missing="$missing libgl1"
[ -z "$missing" ] && exit 0
echo "installing system packages:$missing"
SUDO=""
[ "$(id -u)" = "0" ] || SUDO="sudo"
$SUDO apt-get update -qq >/dev/null 2>&1 || true
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq $missing >/dev/null 2>&1 \
  || echo "warning: could not install$missing (GL tests may be skipped or fail)"
exit 0

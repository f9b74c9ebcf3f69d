#!/bin/sh
# Install the system libraries the project needs when they are missing:
# EGL + Mesa (llvmpipe) for headless OpenGL 4.5; Xvfb, xdotool, xwd and GLX for the
# previewer's window tests.
# Only acts when something is missing; needs root (CI runs as root) or sudo.
missing=""
ldconfig -p 2>/dev/null | grep -q 'libEGL.so.1' || missing="$missing libegl1"
ldconfig -p 2>/dev/null | grep -q 'libEGL_mesa.so.0' || missing="$missing libegl-mesa0 libgl1-mesa-dri"
ldconfig -p 2>/dev/null | grep -q 'libGL.so.1' || missing="$missing libgl1"
# stb preview (GLFW window over GLX) and its window tests (tests/test_preview_window.py):
# an X server (Xvfb), input (xdotool), window capture (xwd), and the X11 libraries GLFW loads.
ldconfig -p 2>/dev/null | grep -q 'libGLX_mesa.so.0' || missing="$missing libglx-mesa0"
for lib in libXrandr.so.2:libxrandr2 libXinerama.so.1:libxinerama1 libXcursor.so.1:libxcursor1 \
  libXi.so.6:libxi6 libXxf86vm.so.1:libxxf86vm1; do
  ldconfig -p 2>/dev/null | grep -q "${lib%%:*}" || missing="$missing ${lib##*:}"
done
command -v Xvfb >/dev/null 2>&1 || missing="$missing xvfb"
command -v xdotool >/dev/null 2>&1 || missing="$missing xdotool"
command -v xwd >/dev/null 2>&1 || missing="$missing x11-apps"
[ -z "$missing" ] && exit 0
echo "installing system packages:$missing"
SUDO=""
[ "$(id -u)" = "0" ] || SUDO="sudo"
$SUDO apt-get update -qq >/dev/null 2>&1 || true
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq $missing >/dev/null 2>&1 \
  || echo "warning: could not install$missing (GL tests may be skipped or fail)"
exit 0

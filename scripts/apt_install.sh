#!/bin/sh
# apt_install.sh PACKAGE PURPOSE — install one Debian package when apt-get is usable (root or passwordless sudo).
# Exit status 0 when installed, 1 when apt is not usable or the install failed (a line on stdout says which).
PKG="$1"
WHY="$2"
SUDO=""
if [ "$(id -u)" != "0" ]; then
    if command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then SUDO="sudo -n"; fi
fi
if command -v apt-get >/dev/null 2>&1 && { [ "$(id -u)" = "0" ] || [ -n "$SUDO" ]; }; then
    echo "ssbench: installing $PKG for $WHY (apt-get)"
    if $SUDO apt-get update -qq >/dev/null 2>&1 && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "$PKG" >/dev/null 2>&1; then
        echo "ssbench: $PKG installed"
        exit 0
    fi
    echo "ssbench: apt-get could not install $PKG"
fi
exit 1

#!/bin/sh
# Make sure a libLLVM >= 19 exists for Dr.Jit's LLVM backend (15 and 16 abort the process; 14 is refused).
# Installs Debian's libllvm19 when apt is usable; otherwise prints the command and carries on: ssbench then
# falls back to Mitsuba's slow scalar_rgb variant.
has_llvm() {
    for f in /usr/lib/*-linux-gnu/libLLVM*.so* /usr/lib/llvm-*/lib/libLLVM*.so* /usr/local/lib/libLLVM*.so*; do
        case "$f" in *LLVM-19*|*LLVM.so.19*|*LLVM-2[0-9]*|*LLVM.so.2[0-9]*|*llvm-19/*|*llvm-2[0-9]/*) [ -e "$f" ] && return 0;; esac
    done
    return 1
}
if has_llvm; then
    exit 0
fi
if sh "$(dirname "$0")/apt_install.sh" libllvm19 "Dr.Jit"; then
    exit 0
fi
echo "ssbench: no libLLVM >= 19 found. Install it with:  sudo apt-get install -y libllvm19"
echo "ssbench: continuing with Mitsuba's scalar_rgb fallback (ground truth ~50x slower)"
exit 0

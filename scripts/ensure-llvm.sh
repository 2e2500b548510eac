#!/usr/bin/env bash
# Make sure a libLLVM >= 16 is present for Mitsuba's fast CPU (llvm_ad_*) variants.
# drjit 1.5 crashes with Debian's LLVM 14/15; Debian's libllvm19 works.
# Installs libllvm19 with apt-get when run as root on Debian/Ubuntu; otherwise
# says so, and gevsim falls back to the (slower) scalar variant with a warning.
set -u
for dir in /usr/lib/x86_64-linux-gnu /usr/lib/aarch64-linux-gnu /usr/lib64 /usr/lib /usr/local/lib; do
    if compgen -G "$dir/libLLVM-1[6-9].so*" >/dev/null || compgen -G "$dir/libLLVM-2[0-2].so*" >/dev/null \
        || compgen -G "$dir/libLLVM.so.1[6-9]*" >/dev/null || compgen -G "$dir/libLLVM.so.2[0-2]*" >/dev/null; then
        exit 0
    fi
done
if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "ensure-llvm: installing libllvm19 for Mitsuba's LLVM variant (apt-get)"
    export DEBIAN_FRONTEND=noninteractive
    apt-get install -y -q libllvm19 >/dev/null 2>&1 \
        || { apt-get update -q >/dev/null 2>&1 && apt-get install -y -q libllvm19 >/dev/null 2>&1; } \
        || echo "ensure-llvm: could not install libllvm19; gevsim will use Mitsuba's scalar variant (slower)"
else
    echo "ensure-llvm: no libLLVM >= 16 found and not root: gevsim will use Mitsuba's scalar variant (slower)." \
         "For the fast one: apt-get install libllvm19 (or set DRJIT_LIBLLVM_PATH to a libLLVM >= 16)."
fi
exit 0

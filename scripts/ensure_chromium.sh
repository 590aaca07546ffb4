#!/bin/sh
# Make sure a Chromium exists for the report's browser test (tests/report/test_browser.py loads the report in
# headless Chromium). Installs Debian's `chromium` when apt is usable; otherwise prints the command and carries
# on: the test then skips with that reason. Best effort: never fails `make test`.
for b in chromium chromium-browser google-chrome; do
    if command -v "$b" >/dev/null 2>&1; then
        exit 0
    fi
done
SUDO=""
if [ "$(id -u)" != "0" ]; then
    if command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then SUDO="sudo -n"; fi
fi
if command -v apt-get >/dev/null 2>&1 && { [ "$(id -u)" = "0" ] || [ -n "$SUDO" ]; }; then
    echo "ssbench: installing chromium for the report's browser test (apt-get; about a minute)"
    if $SUDO apt-get update -qq >/dev/null 2>&1 && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq chromium >/dev/null 2>&1; then
        echo "ssbench: chromium installed"
        exit 0
    fi
    echo "ssbench: apt-get could not install chromium"
fi
echo "ssbench: no Chromium found (chromium, chromium-browser, google-chrome). Install it with:  sudo apt-get install -y chromium"
echo "ssbench: continuing; the report's browser test will be skipped"
exit 0

#!/bin/sh
# Make sure a Chromium exists for the report's browser test (tests/report/test_browser.py loads the report in
# headless Chromium). Installs Debian's `chromium` when apt is usable; otherwise prints the command and carries
# on: the test then skips with that reason. Best effort: never fails `make test`.
for b in chromium chromium-browser google-chrome; do
    if command -v "$b" >/dev/null 2>&1; then
        exit 0
    fi
done
if sh "$(dirname "$0")/apt_install.sh" chromium "the report's browser test (about a minute)"; then
    exit 0
fi
echo "ssbench: no Chromium found (chromium, chromium-browser, google-chrome). Install it with:  sudo apt-get install -y chromium"
echo "ssbench: continuing; the report's browser test will be skipped"
exit 0

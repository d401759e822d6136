#!/usr/bin/env bash
# Install the headless browser the viewer's end-to-end tests drive (Debian's `chromium`, via Playwright).
# Idempotent: does nothing when /usr/bin/chromium exists. Installs only as root with apt-get; otherwise it says how.
set -euo pipefail

CHROMIUM=/usr/bin/chromium

if [ -x "$CHROMIUM" ]; then
    echo "install_browser: $CHROMIUM is present ($("$CHROMIUM" --version 2>/dev/null || echo 'version unknown'))"
    exit 0
fi

if [ "$(id -u)" -eq 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "install_browser: installing Debian's chromium package for the viewer's browser tests"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update
    apt-get install -y --no-install-recommends chromium
    if [ -x "$CHROMIUM" ]; then
        echo "install_browser: installed $("$CHROMIUM" --version 2>/dev/null || echo "$CHROMIUM")"
        exit 0
    fi
    echo "install_browser: apt-get finished but $CHROMIUM is still missing" >&2
    exit 1
fi

cat <<'MSG'
install_browser: /usr/bin/chromium is missing, and this script installs it only as root with apt-get.
The viewer's browser tests (tests/e2e/test_viewer_browser.py) are skipped without it. To install it:
    sudo apt-get update && sudo apt-get install -y chromium
MSG
exit 0

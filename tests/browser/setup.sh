#!/bin/sh
# Installs Debian's chromium for the opt-in browser test (tests/browser/test_certificate_in_chromium.py).
# Run as root where apt works:  sh tests/browser/setup.sh   then   RIG_BROWSER_TESTS=1 pytest tests/browser
set -eu
if command -v chromium >/dev/null 2>&1; then
    echo "chromium is installed: $(chromium --version 2>/dev/null || echo unknown version)"
    exit 0
fi
if [ "$(id -u)" -ne 0 ]; then
    echo "tests/browser/setup.sh: run as root (apt-get install chromium)" >&2
    exit 2
fi
export DEBIAN_FRONTEND=noninteractive
apt-get update -q
apt-get install -y -q --no-install-recommends chromium fonts-dejavu-core
chromium --version

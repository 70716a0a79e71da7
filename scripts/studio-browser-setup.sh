#!/usr/bin/env bash
# Installs what the studio's browser tests need: Debian's Chromium (/usr/bin/chromium, via apt-get
# when missing) and playwright-core (npm ci in crates/motif-studio/e2e). Playwright never downloads
# a browser of its own here: the tests launch /usr/bin/chromium.
#
# Idempotent: apt-get runs only when /usr/bin/chromium is missing, npm ci only when
# e2e/node_modules/playwright-core is missing. Needs root (or sudo) for apt-get.
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
e2e="$repo/crates/motif-studio/e2e"

sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then
    sudo_cmd=(sudo)
fi

if [ ! -x /usr/bin/chromium ]; then
    echo "studio-browser-setup: installing Debian's chromium with apt-get"
    start=$(date +%s)
    "${sudo_cmd[@]}" apt-get update
    "${sudo_cmd[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends chromium fonts-dejavu-core
    echo "studio-browser-setup: apt-get took $(($(date +%s) - start)) s"
else
    echo "studio-browser-setup: /usr/bin/chromium present ($(/usr/bin/chromium --version 2>/dev/null || echo 'version unknown'))"
fi

if ! command -v npm >/dev/null 2>&1; then
    echo "studio-browser-setup: npm is missing; install Debian's nodejs and npm packages" >&2
    exit 1
fi

if [ ! -d "$e2e/node_modules/playwright-core" ]; then
    echo "studio-browser-setup: npm ci in $e2e"
    (cd "$e2e" && PLAYWRIGHT_SKIP_BROWSER_DOWNLOAD=1 npm ci --ignore-scripts --no-audit --no-fund)
else
    echo "studio-browser-setup: playwright-core already installed"
fi

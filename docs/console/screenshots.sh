#!/usr/bin/env bash
# The pictures of docs/console.md: a real `polbrdf serve` filled with the
# api/examples specs, each console page shot in headless Chromium
# (tests/console_browser.rs, `screenshots`). Needs chromium and
# chromium-driver (Debian), as the console tests.
set -euo pipefail
cd "$(dirname "$0")/../.."
POLBRDF_SCREENSHOTS="$(pwd)/docs/console" \
  cargo test --release --test console_browser -- --ignored --exact screenshots --nocapture

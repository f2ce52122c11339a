# Sourced by .ci/run: Debian's Chromium and ChromeDriver for the console's
# browser tests (tests/console_browser.rs, which fail under CI=true without
# them). Exports POLBRDF_TEST_CHROMIUM and POLBRDF_TEST_CHROMEDRIVER.
if [ ! -x /usr/bin/chromium ] || [ ! -x /usr/bin/chromedriver ]; then
  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver > /dev/null
fi
export POLBRDF_TEST_CHROMIUM=/usr/bin/chromium
export POLBRDF_TEST_CHROMEDRIVER=/usr/bin/chromedriver
echo "ci: $(/usr/bin/chromium --version 2>/dev/null), $(/usr/bin/chromedriver --version | cut -d' ' -f1-2)"

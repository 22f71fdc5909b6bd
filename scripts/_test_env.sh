# Shared by scripts/test.sh and .ci/run: the test set-up (./.venv with the test packages, and, when root,
# Debian's Chromium for the browser tests).
source "$(dirname "${BASH_SOURCE[0]}")/_env.sh" test
if [ ! -x /usr/bin/chromium ]; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "==> installing Chromium for the browser tests"
    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null) \
      || echo "warning: could not install chromium; browser tests will be skipped" >&2
  else
    echo "note: /usr/bin/chromium missing and not root; browser tests will be skipped" >&2
  fi
fi

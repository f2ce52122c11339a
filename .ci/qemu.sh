# Sourced by .ci/run: Debian's qemu-user for tests/service_simd.rs, which
# solves one spec on an emulated CPU of another SIMD level (qemu-x86_64
# -cpu Haswell: AVX2 without AVX-512) and fails under CI=true without it.
# Exports POLBRDF_TEST_QEMU.
if [ ! -x /usr/bin/qemu-x86_64 ]; then
  apt-get update -qq && apt-get install -y -qq qemu-user > /dev/null
fi
export POLBRDF_TEST_QEMU=/usr/bin/qemu-x86_64
echo "ci: $("$POLBRDF_TEST_QEMU" --version | head -n 1)"

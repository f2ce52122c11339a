# Sourced by .ci/run: a real S3-compatible server on loopback for the farm
# tests (tests/service_farm.rs), which fail under CI=true without one: the
# `moto` server (PyPI, server mode; not a mock inside our process), on a
# free port, with one bucket. Exports POLBRDF_TEST_S3 and the AWS_*
# variables the service reads; call stop_s3 on exit.
s3_started=$(date +%s)
if ! command -v moto_server > /dev/null; then
  python3 -m pip install -q 'moto[server]' 2> /dev/null
fi
s3_port=55900
while (: < "/dev/tcp/127.0.0.1/$s3_port") 2> /dev/null; do s3_port=$((s3_port + 1)); done
s3_log=$(mktemp "${TMPDIR:-/tmp}/polbrdf-moto.XXXXXX")
moto_server -H 127.0.0.1 -p "$s3_port" > "$s3_log" 2>&1 &
s3_pid=$!
stop_s3() {
  kill "$s3_pid" 2> /dev/null || true
  wait "$s3_pid" 2> /dev/null || true
  rm -f "$s3_log"
}
for _ in $(seq 100); do
  curl -s -o /dev/null "http://127.0.0.1:$s3_port/" && break
  sleep 0.1
done
# moto accepts any credentials; the service signs its requests regardless.
curl -s -f -o /dev/null -X PUT "http://127.0.0.1:$s3_port/polbrdf-test"
export POLBRDF_TEST_S3="s3://polbrdf-test/ci"
export AWS_ENDPOINT_URL="http://127.0.0.1:$s3_port"
export AWS_REGION=us-east-1
export AWS_ACCESS_KEY_ID=polbrdf-test
export AWS_SECRET_ACCESS_KEY=polbrdf-test
export AWS_ALLOW_HTTP=true
echo "ci: moto $(python3 -c 'import moto; print(moto.__version__)') S3 on port $s3_port," \
  "ready in $(($(date +%s) - s3_started)) s"

# Sourced by .ci/run: a throw-away PostgreSQL cluster for the tests of the
# PostgreSQL index (src/storage/index, tests/service_postgres.rs), which fail
# under CI=true without one. Exports POLBRDF_TEST_DATABASE_URL; call
# stop_postgres on exit.
#
# Debian's server package is installed if missing (its binaries live in
# /usr/lib/postgresql/<version>/bin). initdb refuses to run as root, so the
# cluster belongs to the package's `postgres` user (created here if the
# package was installed some other way). It listens on 127.0.0.1 only, on a
# free port, with its socket in its own temporary directory, trust auth
# (nothing but this run can reach it) and fsync off (its data is thrown away).
pg_started=$(date +%s)
# The newest installed server's binaries (nothing, not a failure, if none).
pg_newest_bin() { ls -d /usr/lib/postgresql/*/bin 2> /dev/null | sort -V | tail -n 1 || true; }
pg_bin=$(pg_newest_bin)
if [ ! -x "$pg_bin/initdb" ]; then
  apt-get update -qq && apt-get install -y -qq postgresql > /dev/null
  pg_bin=$(pg_newest_bin)
fi
id -u postgres > /dev/null 2>&1 || useradd --system --no-create-home postgres
pg_dir=$(mktemp -d "${TMPDIR:-/tmp}/polbrdf-pg.XXXXXX")
chown postgres "$pg_dir"
stop_postgres() {
  if [ -e "$pg_dir/data/postmaster.pid" ]; then
    # From / : the postgres user may not enter the current directory.
    (cd / && runuser -u postgres -- "$pg_bin/pg_ctl" -D "$pg_dir/data" -m fast -w stop > /dev/null) || true
  fi
  rm -rf "$pg_dir"
}
pg_port=55432
while (: < "/dev/tcp/127.0.0.1/$pg_port") 2> /dev/null; do pg_port=$((pg_port + 1)); done
runuser -u postgres -- "$pg_bin/initdb" -D "$pg_dir/data" -U polbrdf --auth=trust \
  -E UTF8 --no-locale > "$pg_dir/initdb.log"
runuser -u postgres -- "$pg_bin/pg_ctl" -D "$pg_dir/data" -l "$pg_dir/server.log" -w \
  -o "-c listen_addresses=127.0.0.1 -p $pg_port -k $pg_dir -c fsync=off" start > /dev/null
"$pg_bin/createdb" -h 127.0.0.1 -p "$pg_port" -U polbrdf polbrdf_test
export POLBRDF_TEST_DATABASE_URL="postgres://polbrdf@127.0.0.1:$pg_port/polbrdf_test"
echo "ci: PostgreSQL $("$pg_bin/postgres" --version | awk '{print $3}') on port $pg_port," \
  "ready in $(($(date +%s) - pg_started)) s"

#!/usr/bin/env bash
# Checks of deploy/ that this machine can make (run by .ci/run after the
# tests; or by hand: .ci/deploy-check.sh target/release/polbrdf):
#
# * deploy/systemd/polbrdf.service passes `systemd-analyze verify`. verify
#   fails on an ExecStart binary that does not exist, and /usr/local/bin/polbrdf
#   does not here, so it checks a copy whose ExecStart is the binary given as
#   the argument (default target/release/polbrdf); everything else is the
#   shipped text. DynamicUser needs no user to exist.
# * Every YAML file under deploy/ (compose, Kubernetes) parses, with
#   duplicate keys refused (PyYAML would keep the last one silently).
#
# Not checked: deploy/Containerfile and deploy/compose.yaml are not built or
# run (no container engine here), and the manifests are not applied. The
# nginx config is checked by .ci/nginx.sh (nginx -t) and tests/service_nginx.rs.
set -euo pipefail
cd "$(dirname "$0")/.."
binary=$(realpath -m "${1:-target/release/polbrdf}")
if [ ! -x "$binary" ]; then
  echo "deploy-check: $binary is not an executable (build it, or name it as the argument)" >&2
  exit 1
fi
if ! command -v systemd-analyze > /dev/null; then
  apt-get update -qq && apt-get install -y -qq systemd > /dev/null
fi
if ! python3 -c 'import yaml' 2> /dev/null; then
  # A Debian python3 refuses pip installs (PEP 668): its package then.
  python3 -m pip install --quiet pyyaml 2> /dev/null ||
    { apt-get update -qq && apt-get install -y -qq python3-yaml > /dev/null; }
fi

check=$(mktemp -d "${TMPDIR:-/tmp}/polbrdf-deploy-check.XXXXXX")
trap 'rm -rf "$check"' EXIT
unit=deploy/systemd/polbrdf.service
grep -q '^ExecStart=/usr/local/bin/polbrdf serve$' "$unit" ||
  { echo "deploy-check: $unit: ExecStart is not /usr/local/bin/polbrdf serve" >&2; exit 1; }
sed "s|^ExecStart=/usr/local/bin/polbrdf |ExecStart=$binary |" "$unit" > "$check/polbrdf.service"
# verify prints its complaints but may still exit 0 for some: fail on any.
systemd-analyze verify --recursive-errors=no "$check/polbrdf.service" > "$check/verify.log" 2>&1 ||
  { cat "$check/verify.log" >&2; exit 1; }
if [ -s "$check/verify.log" ]; then
  cat "$check/verify.log" >&2
  exit 1
fi

python3 - <<'PY'
import pathlib, sys, yaml

class Strict(yaml.SafeLoader):
    pass

def mapping(loader, node, deep=False):
    # Duplicates among the keys written in this mapping; keys that a `<<`
    # merge brings in may be overridden (what merges are for).
    seen = set()
    for key_node, _ in node.value:
        if key_node.tag == "tag:yaml.org,2002:merge":
            continue
        key = loader.construct_object(key_node, deep=True)
        if key in seen:
            raise yaml.constructor.ConstructorError(
                None, None, f"duplicate key {key!r}", key_node.start_mark)
        seen.add(key)
    return loader.construct_mapping(node, deep)

Strict.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, mapping)
files = sorted(p for p in pathlib.Path("deploy").rglob("*") if p.suffix in (".yaml", ".yml"))
for p in files:
    try:
        docs = [d for d in yaml.load_all(p.read_text(), Loader=Strict)]
    except yaml.YAMLError as e:
        sys.exit(f"deploy-check: {p}: {e}")
    if not docs or any(d is None for d in docs):
        sys.exit(f"deploy-check: {p}: an empty document")
print(f"deploy-check: {len(files)} YAML files under deploy/ parse")
PY
echo "deploy-check: $unit passes systemd-analyze verify (ExecStart=$binary)"

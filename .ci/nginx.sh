# Sourced by .ci/run: nginx for tests/service_nginx.rs (which fails under
# CI=true without one) and a syntax check of the shipped front-end config.
# Exports POLBRDF_TEST_NGINX.
#
# Debian's nginx-light is installed if /usr/sbin/nginx is missing (on
# bookworm it is nginx plus the small echo module; deploy/nginx needs only
# modules built into nginx itself). `nginx -t` resolves the upstream host
# names of deploy/nginx/polbrdf.conf (compose service names), so the check
# runs on a copy whose `server` lines point at a stub 127.0.0.1 address and
# whose cache lives in a temporary directory; everything else is the
# shipped text of deploy/nginx/nginx.conf and polbrdf.conf.
if [ ! -x /usr/sbin/nginx ]; then
  apt-get update -qq && apt-get install -y -qq nginx-light > /dev/null
fi
ngx_check=$(mktemp -d "${TMPDIR:-/tmp}/polbrdf-nginx.XXXXXX")
cp deploy/nginx/nginx.conf "$ngx_check/nginx.conf"
sed -e '/# BEGIN polbrdf servers/,/# END polbrdf servers/c\    server 127.0.0.1:9;' \
  -e "s|^proxy_cache_path [^ ]*|proxy_cache_path $ngx_check/cache|" \
  deploy/nginx/polbrdf.conf > "$ngx_check/polbrdf.conf"
ngx_rc=0
/usr/sbin/nginx -q -t -p "$ngx_check" -e "$ngx_check/error.log" -c "$ngx_check/nginx.conf" || ngx_rc=$?
rm -rf "$ngx_check"
if [ "$ngx_rc" -ne 0 ]; then
  echo "ci: deploy/nginx fails nginx -t" >&2
  exit "$ngx_rc"
fi
export POLBRDF_TEST_NGINX=/usr/sbin/nginx
echo "ci: $(/usr/sbin/nginx -v 2>&1 | sed 's/.*: //'), deploy/nginx passes nginx -t"

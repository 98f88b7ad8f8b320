# Sourced by scripts/setup.sh and scripts/sanitize.sh.
# ensure_packages WHO PACKAGE...: installs the Debian packages that are
# missing (as root, or through sudo), quietly, with no question asked; exits
# with one line naming them when that is not possible. WHO prefixes messages.
ensure_packages() {
  local who="$1"
  shift
  local missing=() p status
  for p in "$@"; do
    status=$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)
    [ "$status" = "install ok installed" ] || missing+=("$p")
  done
  [ "${#missing[@]}" -gt 0 ] || return 0
  echo "$who: installing ${missing[*]}" >&2
  local sudo=""
  if [ "$(id -u)" != 0 ]; then
    if command -v sudo >/dev/null; then sudo="sudo"; else
      echo "$who: missing packages (${missing[*]}) and not root: install them with apt-get as root" >&2
      exit 1
    fi
  fi
  local log="/tmp/ddhgs-$who-apt.log" began=$SECONDS
  if ! { $sudo env DEBIAN_FRONTEND=noninteractive apt-get update -qq >/dev/null &&
         $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
           --no-install-recommends "${missing[@]}" >"$log" 2>&1; }; then
    echo "$who: apt-get could not install: ${missing[*]} (log: $log)" >&2
    tail -5 "$log" >&2 || true
    exit 1
  fi
  echo "$who: installed ${#missing[@]} package(s) in $((SECONDS - began)) s" >&2
}

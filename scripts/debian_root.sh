#!/usr/bin/env bash
# A cached Debian root (13 "trixie": DOLFINx 0.9, or 12 "bookworm": DOLFINx 0.5.2) with
# Debian's DOLFINx stack, for running the project's tests against the other DOLFINx version
# than the host's (.ci/run: on a Debian 12 host trixie, on a Debian 13 host bookworm).
#
#   scripts/debian_root.sh [--suite trixie|bookworm] [--repo DIR] [--venv NAME] -- CMD ARGS...
#   scripts/debian_root.sh -- make test
#   scripts/debian_root.sh --venv pip -- make test DOLFINX=pip     (DOLFINx 0.11 from PyPI)
#   scripts/debian_root.sh --suite bookworm -- python3 -c 'import dolfinx; print(dolfinx.__version__)'
#   scripts/debian13_root.sh ...         (the same as --suite trixie, the default)
#
# Builds the root at ${FM_TRIXIE_ROOT:-/var/tmp/fm-trixie} (bookworm: FM_BOOKWORM_ROOT,
# /var/tmp/fm-bookworm) if it is missing or was left half-built (the stamp file is written
# only after every step succeeded), then runs CMD inside it (as root, in DIR) with DIR
# (default: this repository) bind-mounted at the same path. /proc, /sys, /dev (with
# /dev/pts, /dev/shm: Open MPI's shared memory) and the host's /tmp are mounted too, and the
# host's CA bundle (read-only) over the root's.
#
# The mounts are made in a private mount namespace (unshare -m), so they are never seen by
# the host and vanish with the command even if it is killed; a trap unmounts them as well.
# A flock serialises building; running is shared, so several commands may run at once.
#
# DIR/.venv (the host's venv, another Python) is hidden inside the root behind a venv kept
# in the root (ROOT/var/lib/fm-venvs/<hash of DIR>[-NAME]), so `make test` works unchanged in
# both; the host's .venv is never touched. --venv NAME keeps another venv for the same DIR
# (the pip route's beside the apt route's).
# CMD gets a clean environment (PATH, HOME=/root, LANG, CI, Open MPI's run-as-root and
# oversubscribe switches); pass more with `-- env VAR=value CMD...`.
# Needs root, debootstrap (installed with apt-get if missing) and the network to the
# machine's Debian archive (read from its apt sources; where they name none, set
# FM_<SUITE>_MIRROR). Environment, per suite (TRIXIE or BOOKWORM): FM_<SUITE>_ROOT,
# FM_<SUITE>_MIRROR (the archive's URL), FM_<SUITE>_EXTRA_PKGS (more packages; a changed
# list installs them into the cached root).
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
repo=$(cd "$here/.." && pwd)
SUITE=trixie
VENV=""
usage="usage: $0 [--suite trixie|bookworm] [--repo DIR] [--venv NAME] -- CMD ARGS..."
while [ $# -gt 0 ]; do
  case "$1" in
    --suite) SUITE=${2:-}; shift 2 ;;
    --suite=*) SUITE=${1#--suite=}; shift ;;
    --repo) repo=$(cd "$2" && pwd); shift 2 ;;
    --repo=*) repo=$(cd "${1#--repo=}" && pwd); shift ;;
    --venv) VENV=${2:-}; shift 2 ;;
    --venv=*) VENV=${1#--venv=}; shift ;;
    --) shift; break ;;
    -h|--help) sed -n '2,/^set -euo/{/^#/s/^# \{0,1\}//p}' "${BASH_SOURCE[0]}"; exit 0 ;;
    *) echo "debian_root: unknown argument '$1' ($usage)" >&2; exit 2 ;;
  esac
done
case "$SUITE" in
  trixie|bookworm) ;;
  *) echo "debian_root: suite '$SUITE' is not one the project runs on: trixie (Debian 13) or bookworm (Debian 12)" >&2; exit 2 ;;
esac
[ $# -gt 0 ] || { echo "debian_root: no command ($usage)" >&2; exit 2; }
case "$VENV" in
  ""|[A-Za-z0-9]|[A-Za-z0-9][A-Za-z0-9_-]*) ;;
  *) echo "debian_root: --venv '$VENV': letters, digits, '-' and '_' only" >&2; exit 2 ;;
esac
[ "$(id -u)" -eq 0 ] || { echo "debian_root: must run as root (debootstrap, chroot, mount)" >&2; exit 1; }

# FM_TRIXIE_ROOT, FM_TRIXIE_MIRROR, FM_TRIXIE_EXTRA_PKGS (or FM_BOOKWORM_...)
var=FM_${SUITE^^}
root_var=${var}_ROOT mirror_var=${var}_MIRROR extra_var=${var}_EXTRA_PKGS
ROOT=${!root_var:-/var/tmp/fm-$SUITE}
ROOT=${ROOT%/}
case "$ROOT" in
  /?*/?*) ;;   # absolute, at least two levels deep: never / or /var by mistake
  *) echo "debian_root: $root_var='$ROOT' must be an absolute path like /var/tmp/fm-$SUITE" >&2; exit 2 ;;
esac
STAMP="$ROOT/.fm-$SUITE-complete"
BASE_STAMP="$ROOT/.fm-$SUITE-debootstrap-done"
LOCK="$ROOT.lock"
PKGS=(python3-dolfinx-real python3-gmsh python3-pytest python3-matplotlib python3-scipy
      python3-pil openmpi-bin python3-venv python3-setuptools python3-wheel python3-pip
      make git ca-certificates
      # FFCx JIT: cffi compiles the generated C with the system compiler and Python headers.
      gcc g++ python3-dev pkg-config
      ${!extra_var:-})
PKG_LIST="${PKGS[*]}"

log() { echo "debian_root ($SUITE): $*" >&2; }

# The archive this machine's apt already uses (the only Debian mirror reachable here).
mirror() {
  if [ -n "${!mirror_var:-}" ]; then echo "${!mirror_var}"; return; fi
  local f url
  for f in /etc/apt/sources.list.d/*.sources; do
    [ -f "$f" ] || continue
    # deb822: the URIs line of a stanza whose Suites has a plain Debian suite.
    url=$(awk 'BEGIN{RS=""} /Suites:[^\n]*(bookworm|trixie|stable)( |\n|$)/ && !/security/ {
                 if (match($0, /URIs:[ \t]*[^ \t\n]+/)) { s=substr($0,RSTART,RLENGTH);
                   sub(/URIs:[ \t]*/,"",s); print s; exit } }' "$f")
    [ -n "$url" ] && { echo "$url"; return; }
  done
  for f in /etc/apt/sources.list /etc/apt/sources.list.d/*.list; do
    [ -f "$f" ] || continue
    url=$(awk '$1=="deb" { u=""; for (i=2;i<=NF;i++) if ($i ~ /^[a-z]+:\/\//) { u=$i; s=$(i+1); break }
                 if (u!="" && u ~ /debian\/?$/ && s !~ /security/) { print u; exit } }' "$f")
    [ -n "$url" ] && { echo "$url"; return; }
  done
  log "found no Debian archive in this machine's apt sources (/etc/apt/sources.list," \
      "/etc/apt/sources.list.d/); set $mirror_var to the URL of a Debian archive this" \
      "machine reaches (the one its apt uses), e.g. $mirror_var=http://HOST/debian"
  return 1
}

# Refuse to touch a root that still has something mounted below it (a crashed run
# without a mount namespace): rm -rf would go through a bind-mounted repository.
assert_no_mounts() {
  if awk -v r="$ROOT" '$5==r || index($5, r"/")==1 {found=1} END{exit !found}' /proc/self/mountinfo; then
    log "something is mounted under $ROOT; unmount it first:"
    awk -v r="$ROOT" '$5==r || index($5, r"/")==1 {print "  " $5}' /proc/self/mountinfo >&2
    exit 1
  fi
}

# ------------------------------------------------------------------------------- build
build() {
  assert_no_mounts
  if [ ! -f "$BASE_STAMP" ]; then
    if [ -e "$ROOT" ]; then log "removing half-built $ROOT"; rm -rf --one-file-system "$ROOT"; fi
    if ! command -v debootstrap >/dev/null; then
      log "installing debootstrap"
      apt-get update -q
      DEBIAN_FRONTEND=noninteractive apt-get install -y -q debootstrap
    fi
    local m; m=$(mirror) || exit 1
    log "debootstrap --variant=minbase $SUITE $ROOT $m"
    mkdir -p "$ROOT"
    # In a private mount namespace: whatever debootstrap mounts cannot leak to the host.
    unshare --mount --propagation private \
      debootstrap --variant=minbase "$SUITE" "$ROOT" "$m"
    # Same archive inside the root, the suite's own.
    rm -f "$ROOT/etc/apt/sources.list"
    cat >"$ROOT/etc/apt/sources.list.d/debian.sources" <<EOF
Types: deb
URIs: $m
Suites: $SUITE $SUITE-updates
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg
EOF
    touch "$BASE_STAMP"
  fi
  cp -L /etc/resolv.conf "$ROOT/etc/resolv.conf"
  log "installing: $PKG_LIST"
  # (dpkg --configure -a: finish what an interrupted earlier attempt left half-installed)
  in_root "" sh -c 'dpkg --configure -a && apt-get update -q &&
    DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "$@" &&
    apt-get clean' sh "${PKGS[@]}"
  # Warm the FFCx/basix JIT and check that DOLFINx imports.
  in_root "" python3 -c 'import dolfinx, dolfinx.fem, ufl, basix, gmsh, petsc4py; print("dolfinx", dolfinx.__version__)' >&2
  printf '%s\n' "$PKG_LIST" >"$STAMP"
}

# ------------------------------------------------------------------------------- run
# in_root REPO CMD...: mount, chroot, run, unmount — inside a private mount namespace.
# (The inner script goes in as an argument: CMD keeps this script's stdin.)
in_root() {
  local r="$1"; shift
  SUITE="$SUITE" unshare --mount --propagation private /bin/bash -c "$INNER" fm-debian-root-inner "$ROOT" "$r" "$VENV" "$@"
}

read -r -d '' INNER <<'INNER' || true
set -euo pipefail
ROOT=$1 REPO=$2 VENV=$3; shift 3
mounted=()
cleanup() {
  local i
  for ((i=${#mounted[@]}-1; i>=0; i--)); do umount -l "${mounted[i]}" 2>/dev/null || true; done
}
trap cleanup EXIT
trap 'exit 130' INT TERM HUP
mnt() { mount "$@"; mounted+=("${@: -1}"); }
# The root itself a mount point, as / is on a real machine: unshare --propagation (this
# script run inside such a root, .ci/run on a Debian 13 host simulated) needs one.
mnt --bind "$ROOT" "$ROOT"
mnt -t proc proc "$ROOT/proc"
mnt --rbind /dev "$ROOT/dev"          # with /dev/pts and /dev/shm (Open MPI's shared memory)
mountpoint -q "$ROOT/dev/shm" || mnt -t tmpfs -o mode=1777 shm "$ROOT/dev/shm"
mnt -t sysfs sysfs "$ROOT/sys"        # hwloc (Open MPI) reads the topology from /sys
mnt --bind /tmp "$ROOT/tmp"           # the host's /tmp: scripts and test output stay visible
# The host's CA bundle, read-only over the root's: where TLS goes through a proxy with its
# own certificate authority, pip (scripts/setup.sh installs ruff) and git get through from
# inside the root as they do on the host.
crt=/etc/ssl/certs/ca-certificates.crt
if [ -f "$crt" ] && [ -f "$ROOT$crt" ]; then
  mnt --bind "$crt" "$ROOT$crt"
  mount -o remount,bind,ro "$ROOT$crt"
fi
if [ -n "$REPO" ]; then
  mkdir -p "$ROOT$REPO"
  mnt --bind "$REPO" "$ROOT$REPO"
  # Hide the host's venv behind one of the root's own (a different Python). In a checkout
  # without one yet, an empty .venv is made first, so that scripts/setup.sh run in here
  # never leaves the root's venv (another Python) for the host to trip over.
  if [ -f "$REPO/scripts/setup.sh" ] && [ ! -e "$REPO/.venv" ]; then mkdir "$REPO/.venv"; fi
  if [ -d "$REPO/.venv" ]; then
    key=$(printf '%s' "$REPO" | md5sum | cut -c1-12)${VENV:+-$VENV}
    mkdir -p "$ROOT/var/lib/fm-venvs/$key"
    mnt --bind "$ROOT/var/lib/fm-venvs/$key" "$ROOT$REPO/.venv"
  fi
  cd "$ROOT$REPO"
  wd=$REPO
else
  wd=/
fi
# A clean environment: nothing of the host's Python or paths.
set +e
chroot "$ROOT" /usr/bin/env -i \
  PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin \
  HOME=/root LANG=C.UTF-8 LC_ALL=C.UTF-8 TERM="${TERM:-dumb}" ${CI:+CI=$CI} \
  DEBIAN_FRONTEND=noninteractive \
  OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 \
  OMPI_MCA_rmaps_base_oversubscribe=1 PRTE_MCA_rmaps_default_mapping_policy=:oversubscribe \
  OMPI_MCA_btl_tcp_if_include=lo \
  FM_IN_DEBIAN_ROOT="$SUITE" \
  /bin/sh -c 'cd "$1" && shift && exec "$@"' sh "$wd" "$@"
rc=$?
exit $rc
INNER

mkdir -p "$(dirname "$ROOT")"
exec 9>"$LOCK"
if [ ! -f "$STAMP" ] || [ "$(cat "$STAMP")" != "$PKG_LIST" ]; then
  flock -n 9 || { log "waiting for another invocation building $ROOT"; flock 9; }
  # Another invocation may have finished the build while we waited.
  if [ ! -f "$STAMP" ] || [ "$(cat "$STAMP")" != "$PKG_LIST" ]; then
    rm -f "$STAMP"
    t0=$(date +%s)
    build
    log "root ready in $(( $(date +%s) - t0 )) s"
  fi
  flock -u 9
fi
# Shared lock while running: a rebuild (exclusive) waits for running commands.
flock -s -n 9 || { log "waiting: $ROOT is being rebuilt"; flock -s 9; }
in_root "$repo" "$@"

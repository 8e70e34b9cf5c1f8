#!/usr/bin/env bash
# The Debian 13 (trixie, DOLFINx 0.9) root: scripts/debian_root.sh --suite trixie.
#   scripts/debian13_root.sh [--repo DIR] -- CMD ARGS...
exec "$(dirname "${BASH_SOURCE[0]}")/debian_root.sh" --suite trixie "$@"

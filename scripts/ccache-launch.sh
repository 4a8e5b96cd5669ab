#!/bin/sh
# The compiler launcher of scripts/build.sh and of the container image's build: ccache, set
# so that two checkouts at different paths with the same Debian compiler share objects (the
# host build in test.sh, then the image's build of /src in deploy/smoke-test.sh, which
# mounts the host's cache). Paths are hashed relative to the checkout, the compiler by its
# content (not its mtime, which differs between a machine and a fresh image), and the
# locale, which ccache hashes, is fixed.
root=$(cd "$(dirname "$0")/.." && pwd)
unset LC_CTYPE LC_MESSAGES
CCACHE_BASEDIR=$root CCACHE_NOHASHDIR=true CCACHE_COMPILERCHECK=content LANG=C.UTF-8 LC_ALL=C.UTF-8 \
  exec ccache "$@"

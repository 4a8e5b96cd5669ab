#!/usr/bin/env bash
# Makes the local base image docker.io/library/debian:bookworm-slim from Debian's own
# packages (debootstrap), for machines that reach Debian's archive but no image registry.
# Does nothing when the image already exists (pass --force to remake it).
# Trimmed like the official slim image: no apt lists or caches, no docs, man pages or
# locales (and dpkg told to keep them out of later installs).
# Needs root, podman and debootstrap. Env: DEBIAN_MIRROR (default deb.debian.org).
set -euo pipefail

image=docker.io/library/debian:bookworm-slim
mirror="${DEBIAN_MIRROR:-http://deb.debian.org/debian}"

if [ "${1:-}" != "--force" ] && podman image exists "$image"; then
  echo "make-base-image: $image already present, digest" \
    "$(podman image inspect --format '{{.Digest}}' "$image")"
  exit 0
fi

rootfs=$(mktemp -d "${TMPDIR:-/tmp}/skinserve-rootfs.XXXXXX")
trap 'rm -rf "$rootfs"' EXIT

echo "make-base-image: debootstrap bookworm (minbase) from $mirror (about 30-60 s)"
debootstrap --variant=minbase bookworm "$rootfs" "$mirror" >"$rootfs.log" 2>&1 || {
  tail -20 "$rootfs.log" >&2
  rm -f "$rootfs.log"
  echo "make-base-image: debootstrap failed" >&2
  exit 1
}
rm -f "$rootfs.log"

# What the official slim image does: keep docs, man pages and locales out for good.
cat >"$rootfs/etc/dpkg/dpkg.cfg.d/docker-slim" <<'EOF'
path-exclude /usr/share/doc/*
path-include /usr/share/doc/*/copyright
path-exclude /usr/share/man/*
path-exclude /usr/share/groff/*
path-exclude /usr/share/info/*
path-exclude /usr/share/lintian/*
path-exclude /usr/share/linda/*
path-exclude /usr/share/locale/*
EOF
cat >"$rootfs/etc/apt/apt.conf.d/docker-clean" <<'EOF'
DPkg::Post-Invoke { "rm -f /var/cache/apt/archives/*.deb /var/cache/apt/archives/partial/*.deb /var/cache/apt/*.bin || true"; };
APT::Update::Post-Invoke { "rm -f /var/cache/apt/archives/*.deb /var/cache/apt/archives/partial/*.deb /var/cache/apt/*.bin || true"; };
Dir::Cache::pkgcache "";
Dir::Cache::srcpkgcache "";
EOF
echo 'Acquire::Languages "none";' >"$rootfs/etc/apt/apt.conf.d/docker-no-languages"
find "$rootfs/usr/share/doc" -mindepth 1 -not -name copyright -not -type d -delete
find "$rootfs/usr/share/doc" -mindepth 1 -type d -empty -delete
rm -rf "$rootfs"/usr/share/man/* "$rootfs"/usr/share/info/* "$rootfs"/usr/share/locale/* \
  "$rootfs"/var/lib/apt/lists/* "$rootfs"/var/cache/apt/*.bin "$rootfs"/var/cache/apt/archives/*.deb \
  "$rootfs"/var/log/*.log "$rootfs"/var/log/apt/*

tar -C "$rootfs" -c . | podman import - "$image" >/dev/null
echo "make-base-image: imported $image ($(podman image inspect --format '{{.Size}}' "$image") bytes)"
# deploy/Dockerfile pins its base by digest: build on this one with
#   --build-arg BASE_IMAGE=docker.io/library/debian@<digest>
echo "make-base-image: digest $(podman image inspect --format '{{.Digest}}' "$image")"

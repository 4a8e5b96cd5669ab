#!/usr/bin/env bash
# Makes a private CA and certificates signed by it, for trying TLS and mutual TLS and for
# the tests (docs/security.md). Not for production: the keys are unencrypted and the CA is
# made on the spot.
#   make-dev-certs.sh DIR [NAME...]
# writes into DIR (created):
#   ca.pem, ca.key              the CA ("skinserve dev CA <DIR's name>")
#   server.pem, server.key      the server: CN=skinserve, SANs localhost, skinserve,
#                               127.0.0.1 and ::1 (serverAuth)
#   NAME.pem, NAME.key          a client per NAME (default: operator renderer): CN=NAME,
#                               O=skinserve, SAN URI spiffe://skinserve/NAME (clientAuth):
#                               the principal an authorization policy names
# EC P-256 keys, valid 30 days. Needs openssl.
set -euo pipefail
if [ $# -lt 1 ]; then
  echo "usage: $0 DIR [CLIENT-NAME...]" >&2
  exit 2
fi
dir=$1
shift
clients=("$@")
[ ${#clients[@]} -gt 0 ] || clients=(operator renderer)
command -v openssl >/dev/null || { echo "make-dev-certs: openssl is not installed" >&2; exit 1; }
mkdir -p "$dir"
cd "$dir"
umask 077

key() { openssl genpkey -algorithm EC -pkeyopt ec_paramgen_curve:P-256 -out "$1" 2>/dev/null; }

# sign NAME SUBJECT EXTENSIONS: NAME.key and NAME.pem, signed by ca.pem.
sign() {
  key "$1.key"
  openssl req -new -key "$1.key" -subj "$2" -out "$1.csr" 2>/dev/null
  printf '%s\n' "$3" >"$1.ext"
  openssl x509 -req -in "$1.csr" -CA ca.pem -CAkey ca.key -CAcreateserial -days 30 \
    -sha256 -extfile "$1.ext" -out "$1.pem" 2>/dev/null
  rm -f "$1.csr" "$1.ext"
}

key ca.key
openssl req -x509 -new -key ca.key -sha256 -days 30 -out ca.pem \
  -subj "/O=skinserve/CN=skinserve dev CA $(basename "$(pwd)")" \
  -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,keyCertSign,cRLSign" \
  2>/dev/null
sign server "/O=skinserve/CN=skinserve" "basicConstraints=CA:FALSE
keyUsage=critical,digitalSignature
extendedKeyUsage=serverAuth
subjectAltName=DNS:localhost,DNS:skinserve,IP:127.0.0.1,IP:::1"
for name in "${clients[@]}"; do
  sign "$name" "/O=skinserve/CN=$name" "basicConstraints=CA:FALSE
keyUsage=critical,digitalSignature
extendedKeyUsage=clientAuth
subjectAltName=URI:spiffe://skinserve/$name"
done
rm -f ca.srl
chmod 0644 ./*.pem
echo "make-dev-certs: $(pwd): ca, server and ${clients[*]} (.pem and .key)"

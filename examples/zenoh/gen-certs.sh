#!/bin/sh
# Certificates for Ayllu over Zenoh with TLS (docs/zenoh.md, "Three machines"): one certificate
# authority, the router's certificate, and one client certificate per robot whose common name
# (CN) is the robot's name, which Zenoh's access control names (router.json5, `cert_common_names`).
#
# Usage: examples/zenoh/gen-certs.sh OUT_DIR ROUTER_NAMES CLIENT...
#   ROUTER_NAMES: the names clients reach the router by, as subjectAltName entries, e.g.
#                 "DNS:router.lab,IP:10.0.0.1" (a client checks the router's certificate names
#                 the host in its tls/HOST:PORT endpoint)
#   CLIENT:       robot names (robot-1 robot-2 ...), each the CN of its certificate
#
# Writes OUT_DIR/router/{ca.pem,router.pem,router.key} for the router's machine and
# OUT_DIR/CLIENT/{ca.pem,robot.pem,robot.key} for each robot: copy each directory to its machine
# as `certs/` beside the configuration file (the example configurations name certs/...).
# OUT_DIR/ca.key signs them all: keep it off the robots. Needs only openssl; EC P-256 keys,
# valid 825 days.
set -eu

if [ $# -lt 3 ]; then
    sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//'
    exit 2
fi
out=$1
router_names=$2
shift 2

mkdir -p "$out/router"
cd "$out"
days=825

# The authority: a self-signed CA certificate (v3, CA:TRUE, as rustls requires).
openssl req -x509 -new -nodes -newkey ec -pkeyopt ec_paramgen_curve:P-256 -keyout ca.key -out ca.pem \
    -days "$days" -subj "/CN=Ayllu team CA" \
    -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,keyCertSign,cRLSign" \
    2>/dev/null

# leaf NAME DIR BASENAME EXTENSIONS: a key and a certificate signed by the authority.
leaf() {
    ext=$(mktemp)
    printf '%s\n' "$4" >"$ext"
    openssl req -new -nodes -newkey ec -pkeyopt ec_paramgen_curve:P-256 -keyout "$2/$3.key" \
        -out "$2/$3.csr" -subj "/CN=$1" 2>/dev/null
    openssl x509 -req -in "$2/$3.csr" -CA ca.pem -CAkey ca.key -CAcreateserial -out "$2/$3.pem" \
        -days "$days" -extfile "$ext" 2>/dev/null
    rm -f "$2/$3.csr" "$ext"
    cp ca.pem "$2/ca.pem"
}

leaf router router router "basicConstraints=CA:FALSE
keyUsage=critical,digitalSignature
extendedKeyUsage=serverAuth
subjectAltName=$router_names"

for client in "$@"; do
    mkdir -p "$client"
    leaf "$client" "$client" robot "basicConstraints=CA:FALSE
keyUsage=critical,digitalSignature
extendedKeyUsage=clientAuth"
done
rm -f ca.srl
echo "certificates in $(pwd): router/ and $*"

# Sourced by scripts/test.sh: throwaway services for the tests that run graybox as it runs
# beyond one machine, each on a free loopback port and stopped when the calling script exits.
# Nothing assumes a system service.
# - `start_postgres VENV`: a PostgreSQL cluster in a temporary directory (as the unprivileged
#   `postgres` user when the script runs as root), accepting TLS with a certificate made for
#   this run (scripts/pg_certs.py, in the test virtualenv VENV); sets GRAYBOX_TEST_POSTGRES to
#   its URL, without a database name, and GRAYBOX_TEST_POSTGRES_CA and
#   GRAYBOX_TEST_POSTGRES_WRONG_CA to the CA that signed the certificate and one that did not.
# - `start_s3 VENV`: an S3 endpoint (moto's server, installed in the test virtualenv VENV) with
#   one bucket; sets the AWS_* variables object_store reads, and GRAYBOX_TEST_BLOBS.

# Runs every stop added, in order, when the script exits.
EXIT_STOPS=()
at_exit() {
  EXIT_STOPS+=("$1")
  trap 'for stop in "${EXIT_STOPS[@]}"; do "$stop"; done' EXIT
}

free_port() {
  python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

pg_tool() {
  local tool=$1 found
  found=$(command -v "$tool" || true)
  if [ -z "$found" ]; then
    found=$(ls /usr/lib/postgresql/*/bin/"$tool" 2> /dev/null | sort -V | tail -n 1 || true)
  fi
  echo "$found"
}

start_postgres() {
  if [ -z "$(pg_tool initdb)" ]; then
    local sudo=""
    if [ "$(id -u)" != 0 ]; then sudo="sudo"; fi
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq postgresql > /dev/null
  fi
  local initdb pg_ctl as=()
  initdb=$(pg_tool initdb) pg_ctl=$(pg_tool pg_ctl)
  PG_DIR=$(mktemp -d)
  if [ "$(id -u)" = 0 ]; then
    chown postgres "$PG_DIR"
    as=(runuser -u postgres --)
  fi
  PG_AS=("${as[@]}") PG_CTL=$pg_ctl
  local port
  port=$(free_port)
  "${as[@]}" "$initdb" -D "$PG_DIR/data" -A trust -U graybox > "$PG_DIR/initdb.log"
  mkdir "$PG_DIR/tls"
  "$1/bin/python" scripts/pg_certs.py "$PG_DIR/tls"
  if [ "$(id -u)" = 0 ]; then chown -R postgres "$PG_DIR/tls"; fi
  # fsync off: the cluster is thrown away, and the tests kill graybox's processes, never the
  # database's. Each test's service opens a pool of up to 8 connections, and they run at once.
  "${as[@]}" "$pg_ctl" -D "$PG_DIR/data" -l "$PG_DIR/log" -w \
    -o "-p $port -k $PG_DIR -c listen_addresses=127.0.0.1 -c fsync=off -c max_connections=300 \
      -c ssl=on -c ssl_cert_file=$PG_DIR/tls/server.pem -c ssl_key_file=$PG_DIR/tls/server.key" \
    start > /dev/null
  at_exit stop_postgres
  export GRAYBOX_TEST_POSTGRES="postgres://graybox@127.0.0.1:$port" \
    GRAYBOX_TEST_POSTGRES_CA="$PG_DIR/tls/ca.pem" GRAYBOX_TEST_POSTGRES_WRONG_CA="$PG_DIR/tls/wrong-ca.pem"
}

stop_postgres() {
  if [ -n "${PG_DIR:-}" ]; then
    "${PG_AS[@]}" "$PG_CTL" -D "$PG_DIR/data" -m immediate stop > /dev/null 2>&1 || true
    rm -rf "$PG_DIR"
  fi
}

start_s3() {
  local venv=$1 port
  port=$(free_port)
  S3_LOG=$(mktemp)
  "$venv/bin/moto_server" -H 127.0.0.1 -p "$port" > "$S3_LOG" 2>&1 &
  S3_PID=$!
  at_exit stop_s3
  export AWS_ENDPOINT="http://127.0.0.1:$port" AWS_ALLOW_HTTP=true AWS_REGION=us-east-1 \
    AWS_ACCESS_KEY_ID=graybox AWS_SECRET_ACCESS_KEY=graybox
  "$venv/bin/python" - << 'EOF'
import os, time
import boto3
s3 = boto3.client("s3", endpoint_url=os.environ["AWS_ENDPOINT"])
for _ in range(100):
    try:
        s3.create_bucket(Bucket="graybox-test")
        break
    except Exception:
        time.sleep(0.1)
else:
    raise SystemExit("the S3 endpoint did not start")
EOF
  export GRAYBOX_TEST_S3=$AWS_ENDPOINT GRAYBOX_TEST_BLOBS=s3://graybox-test
}

stop_s3() {
  if [ -n "${S3_PID:-}" ]; then
    kill "$S3_PID" 2> /dev/null || true
    rm -f "$S3_LOG"
  fi
}

# Sourced by scripts/test.sh: a throwaway PostgreSQL cluster on a free loopback port for the
# tests that run on both databases, started by `start_postgres` (which sets
# GRAYBOX_TEST_POSTGRES to its URL, without a database name) and stopped when the calling
# script exits. Nothing assumes a system service: the cluster lives in a temporary directory
# and runs as the unprivileged `postgres` user when the script runs as root.

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
  port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
  "${as[@]}" "$initdb" -D "$PG_DIR/data" -A trust -U graybox > "$PG_DIR/initdb.log"
  # fsync off: the cluster is thrown away, and the tests kill graybox's processes, never the
  # database's. Each test's service opens a pool of up to 8 connections, and they run at once.
  "${as[@]}" "$pg_ctl" -D "$PG_DIR/data" -l "$PG_DIR/log" -w \
    -o "-p $port -k $PG_DIR -c listen_addresses=127.0.0.1 -c fsync=off -c max_connections=300" \
    start > /dev/null
  trap stop_postgres EXIT
  export GRAYBOX_TEST_POSTGRES="postgres://graybox@127.0.0.1:$port"
}

stop_postgres() {
  if [ -n "${PG_DIR:-}" ]; then
    "${PG_AS[@]}" "$PG_CTL" -D "$PG_DIR/data" -m immediate stop > /dev/null 2>&1 || true
    rm -rf "$PG_DIR"
  fi
}

//! A fault proxy of the tests' own: a TCP proxy on loopback in front of a real service (the
//! S3 endpoint, PostgreSQL) that passes traffic through, refuses it, or holds it without an
//! answer, switched while the service's clients run.

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use tokio::io::AsyncWriteExt;
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::watch;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Everything passes.
    Pass,
    /// New connections are closed at once and open ones are cut: an outage.
    Refuse,
    /// Every connection is held without an answer: a service that hangs.
    Hang,
    /// Requests that delete are held without an answer; the rest pass (each request comes on
    /// a connection of its own: see [`ONE_REQUEST_PER_CONNECTION`]).
    HangDeletes,
}

/// The environment that makes object_store's client open a connection for every request
/// (no idle connection kept), so that the proxy sees each request's method first.
pub const ONE_REQUEST_PER_CONNECTION: (&str, &str) = ("AWS_POOL_MAX_IDLE_PER_HOST", "0");

/// A running proxy; it stops with the runtime it was started on.
pub struct FaultProxy {
    pub addr: SocketAddr,
    mode: watch::Sender<Mode>,
    held: Arc<AtomicUsize>,
}

impl FaultProxy {
    /// A proxy on a free loopback port in front of `upstream`, passing everything.
    pub async fn start(upstream: SocketAddr) -> Self {
        let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap();
        let (mode, watching) = watch::channel(Mode::Pass);
        let held = Arc::new(AtomicUsize::new(0));
        let counter = held.clone();
        tokio::spawn(async move {
            while let Ok((client, _)) = listener.accept().await {
                let (mode, held) = (watching.clone(), counter.clone());
                tokio::spawn(serve(client, upstream, mode, held));
            }
        });
        Self { addr, mode, held }
    }

    pub fn set(&self, mode: Mode) {
        self.mode.send_replace(mode);
    }

    /// Connections held without an answer right now.
    pub fn held(&self) -> usize {
        self.held.load(Ordering::SeqCst)
    }
}

/// What the proxy does with one connection.
async fn serve(
    mut client: TcpStream,
    upstream: SocketAddr,
    mut mode: watch::Receiver<Mode>,
    held: Arc<AtomicUsize>,
) {
    let now = *mode.borrow();
    match now {
        Mode::Refuse => return,
        Mode::Hang => return hold(client, mode, held).await,
        Mode::HangDeletes if is_delete(&client).await => return hold(client, mode, held).await,
        _ => {}
    }
    let Ok(mut server) = TcpStream::connect(upstream).await else {
        return;
    };
    // Passes bytes until either side closes or the mode turns to a fault: a refusal cuts the
    // connection, a hang stops forwarding (and cuts it once the hang ends).
    tokio::select! {
        _ = tokio::io::copy_bidirectional(&mut client, &mut server) => {}
        () = until(&mut mode, |m| matches!(m, Mode::Refuse | Mode::Hang)) => {
            if *mode.borrow() == Mode::Hang {
                held.fetch_add(1, Ordering::SeqCst);
                until(&mut mode, |m| *m != Mode::Hang).await;
                held.fetch_sub(1, Ordering::SeqCst);
            }
        }
    }
    let _ = client.shutdown().await;
}

/// Whether the connection's first request deletes: an HTTP DELETE, or S3's bulk delete
/// (`POST /bucket?delete`, which object_store sends for a delete), read without consuming it.
async fn is_delete(client: &TcpStream) -> bool {
    let mut head = [0u8; 512];
    for _ in 0..100 {
        let n = match client.peek(&mut head).await {
            Ok(0) | Err(_) => return false,
            Ok(n) => n,
        };
        let text = String::from_utf8_lossy(&head[..n]);
        if let Some((line, _)) = text.split_once("\r\n") {
            let mut words = line.split(' ');
            let (method, target) = (words.next().unwrap_or(""), words.next().unwrap_or(""));
            return method == "DELETE" || (method == "POST" && target.contains("?delete"));
        }
        if n == head.len() {
            return false;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    false
}

/// Holds a connection without an answer until the hang ends, then closes it.
async fn hold(client: TcpStream, mut mode: watch::Receiver<Mode>, held: Arc<AtomicUsize>) {
    held.fetch_add(1, Ordering::SeqCst);
    until(&mut mode, |m| !matches!(m, Mode::Hang | Mode::HangDeletes)).await;
    held.fetch_sub(1, Ordering::SeqCst);
    drop(client);
}

/// Resolves once the mode satisfies `done` (at once if it does already).
async fn until(mode: &mut watch::Receiver<Mode>, done: impl Fn(&Mode) -> bool) {
    let _ = mode.wait_for(|m| done(m)).await;
}

/// The address of an `http://host:port` endpoint.
pub fn endpoint_addr(url: &str) -> SocketAddr {
    let hostport = url.trim_start_matches("http://").trim_end_matches('/');
    hostport.parse().unwrap_or_else(|e| panic!("{url}: {e}"))
}

//! A TCP relay between a `polbrdf serve` and a real server (PostgreSQL, the
//! S3-compatible store) that a test can take down and bring back on the
//! same port: while down, connections are refused and the open ones are
//! cut, as when the server restarts or the network drops.

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::watch;

/// The relay; dropped, it stops.
pub struct Proxy {
    /// Its address (`127.0.0.1:PORT`).
    pub addr: SocketAddr,
    up: watch::Sender<bool>,
    stop: Arc<AtomicBool>,
}

impl Proxy {
    /// Relay a free loopback port to `upstream`.
    pub async fn start(upstream: SocketAddr) -> Proxy {
        let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap();
        let (up, _) = watch::channel(true);
        let stop = Arc::new(AtomicBool::new(false));
        tokio::spawn(serve(
            Some(listener),
            addr,
            upstream,
            up.subscribe(),
            stop.clone(),
        ));
        Proxy { addr, up, stop }
    }

    /// Refuse new connections and cut the open ones.
    pub fn down(&self) {
        self.up.send_replace(false);
    }

    /// Accept again, on the same port.
    pub fn up(&self) {
        self.up.send_replace(true);
    }
}

impl Drop for Proxy {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        self.up.send_replace(false);
    }
}

async fn serve(
    mut listener: Option<TcpListener>,
    addr: SocketAddr,
    upstream: SocketAddr,
    mut up: watch::Receiver<bool>,
    stop: Arc<AtomicBool>,
) {
    loop {
        if stop.load(Ordering::SeqCst) {
            return;
        }
        if !*up.borrow() {
            // Closed: connecting is refused until it is up again.
            listener = None;
            let _ = up.wait_for(|u| *u).await;
            continue;
        }
        let l = match &listener {
            Some(l) => l,
            None => {
                listener = TcpListener::bind(addr).await.ok();
                if listener.is_none() {
                    tokio::time::sleep(std::time::Duration::from_millis(20)).await;
                }
                continue;
            }
        };
        tokio::select! {
            accepted = l.accept() => {
                let Ok((mut client, _)) = accepted else { continue };
                let mut down = up.clone();
                tokio::spawn(async move {
                    let Ok(mut server) = TcpStream::connect(upstream).await else { return };
                    tokio::select! {
                        _ = tokio::io::copy_bidirectional(&mut client, &mut server) => {}
                        _ = down.wait_for(|u| !*u) => {}
                    }
                });
            }
            _ = up.changed() => {}
        }
    }
}

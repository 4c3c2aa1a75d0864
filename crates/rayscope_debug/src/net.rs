//! Connections: the accept loop with its connection cap, hyper's per-connection limits and
//! timeouts, and the socket wrapper that turns hyper's own error answers into the API's JSON.

use std::future::Future;
use std::io;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{ready, Context, Poll};
use std::time::Duration;

use axum::Router;
use hyper::server::conn::http1;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::Semaphore;
use tokio::time::Sleep;

use crate::limits::ServerLimits;

/// Largest request head (request line and headers) in bytes.
pub const MAX_HEAD_BYTES: usize = 16 * 1024;
/// Most header lines in a request.
pub const MAX_HEADERS: usize = 64;
/// Longest URL (path and query) the debugger answers; longer ones get a 414.
pub const MAX_URL_BYTES: usize = 8 * 1024;
/// Longest a closing connection keeps reading and discarding what the client still sends (see
/// [`GuardedStream::poll_shutdown`]): time for the rest of a refused upload of a few GiB to
/// arrive over loopback or a fast network. Draining costs no memory, only a connection slot.
const LINGER: Duration = Duration::from_secs(30);
/// A closing connection stops draining once the client has sent nothing for this long (it
/// has stopped sending, and reads its answer).
const LINGER_IDLE: Duration = Duration::from_secs(1);

/// Serves `app` on `listener` until `shutdown` resolves.
///
/// At most `limits.max_connections` connections are open at once; further clients wait in the
/// kernel's listen backlog, so a flood of idle connections cannot use up file descriptors.
pub(crate) async fn serve(
    listener: TcpListener,
    app: Router,
    limits: ServerLimits,
    shutdown: impl Future<Output = ()>,
) {
    let slots = Arc::new(Semaphore::new(limits.max_connections.max(1)));
    let mut http = http1::Builder::new();
    http.timer(TokioTimer::new())
        // Runs from the moment hyper waits for a request head, so it also closes keep-alive
        // connections that stay idle this long.
        .header_read_timeout(limits.header_timeout)
        .max_buf_size(MAX_HEAD_BYTES.max(8192))
        .max_headers(MAX_HEADERS);
    tokio::pin!(shutdown);
    loop {
        let slot = tokio::select! {
            s = slots.clone().acquire_owned() => match s {
                Ok(s) => s,
                Err(_) => return,
            },
            () = &mut shutdown => return,
        };
        let stream = tokio::select! {
            r = listener.accept() => match r {
                Ok((s, _)) => s,
                Err(e) => {
                    // Out of file descriptors or memory: wait for connections to close rather
                    // than spin; a client that gave up (reset, aborted) needs no pause.
                    if !matches!(
                        e.kind(),
                        io::ErrorKind::ConnectionAborted | io::ErrorKind::ConnectionReset
                    ) {
                        tokio::time::sleep(Duration::from_millis(50)).await;
                    }
                    continue;
                }
            },
            () = &mut shutdown => return,
        };
        let _ = stream.set_nodelay(true);
        let io = TokioIo::new(GuardedStream::new(stream, limits.write_timeout));
        let conn = http.serve_connection(io, TowerToHyperService::new(app.clone()));
        tokio::spawn(async move {
            // Errors here are the client's (a reset, a timeout, a malformed head already
            // answered): nothing to report.
            let _ = conn.await;
            drop(slot);
        });
    }
}

/// A TCP stream that fails a write making no progress for `write_timeout` (a client that stops
/// reading), and replaces hyper's empty answers to unreadable request heads with JSON errors.
struct GuardedStream {
    inner: TcpStream,
    write_timeout: Duration,
    stall: Option<Pin<Box<Sleep>>>,
    /// A JSON answer standing in for hyper's, and how much of it is written.
    replacement: Option<(Vec<u8>, usize)>,
    /// Whether our side is shut down for writing; then the end of the lingering read and the
    /// bytes it has discarded.
    write_closed: bool,
    linger: Option<Pin<Box<Sleep>>>,
    idle: Option<Pin<Box<Sleep>>>,
}

impl GuardedStream {
    fn new(inner: TcpStream, write_timeout: Duration) -> Self {
        Self {
            inner,
            write_timeout,
            stall: None,
            replacement: None,
            write_closed: false,
            linger: None,
            idle: None,
        }
    }

    /// Passes a write's result through, failing it once it has been pending too long.
    fn watch<T>(&mut self, cx: &mut Context<'_>, r: Poll<io::Result<T>>) -> Poll<io::Result<T>> {
        if r.is_ready() {
            self.stall = None;
            return r;
        }
        let timeout = self.write_timeout;
        let stall = self.stall.get_or_insert_with(|| Box::pin(tokio::time::sleep(timeout)));
        if stall.as_mut().poll(cx).is_ready() {
            self.stall = None;
            return Poll::Ready(Err(io::Error::new(
                io::ErrorKind::TimedOut,
                "the client stopped reading",
            )));
        }
        Poll::Pending
    }

    /// Writes what is left of the replacement answer.
    fn poll_replacement(&mut self, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        while let Some((bytes, done)) = &mut self.replacement {
            if *done == bytes.len() {
                self.replacement = None;
                break;
            }
            let r = Pin::new(&mut self.inner).poll_write(cx, &bytes[*done..]);
            let n = ready!(self.watch(cx, r))?;
            if n == 0 {
                return Poll::Ready(Err(io::ErrorKind::WriteZero.into()));
            }
            if let Some((_, done)) = &mut self.replacement {
                *done += n;
            }
        }
        Poll::Ready(Ok(()))
    }
}

impl AsyncRead for GuardedStream {
    fn poll_read(mut self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &mut ReadBuf<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_read(cx, buf)
    }
}

impl AsyncWrite for GuardedStream {
    fn poll_write(mut self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &[u8]) -> Poll<io::Result<usize>> {
        let this = &mut *self;
        ready!(this.poll_replacement(cx))?;
        if let Some(json) = replace_parse_error(buf) {
            // hyper's answer counts as written; the JSON one goes out in its place (by the
            // flush and shutdown that follow it, the connection's last writes).
            this.replacement = Some((json, 0));
            return Poll::Ready(Ok(buf.len()));
        }
        let r = Pin::new(&mut this.inner).poll_write(cx, buf);
        this.watch(cx, r)
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let this = &mut *self;
        ready!(this.poll_replacement(cx))?;
        let r = Pin::new(&mut this.inner).poll_flush(cx);
        this.watch(cx, r)
    }

    /// Shuts the writing side, then reads and discards what the client still sends (the rest
    /// of a body refused before it was read) until it closes too, pauses for [`LINGER_IDLE`],
    /// or [`LINGER`] has passed: closing a socket with unread data makes the kernel reset the
    /// connection, and a client still sending then loses the answer it was sent.
    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let this = &mut *self;
        ready!(this.poll_replacement(cx))?;
        if !this.write_closed {
            let r = Pin::new(&mut this.inner).poll_shutdown(cx);
            ready!(this.watch(cx, r))?;
            this.write_closed = true;
        }
        let linger = this.linger.get_or_insert_with(|| Box::pin(tokio::time::sleep(LINGER)));
        let idle = this
            .idle
            .get_or_insert_with(|| Box::pin(tokio::time::sleep(LINGER_IDLE)));
        let mut scratch = [0u8; 16384];
        loop {
            if linger.as_mut().poll(cx).is_ready() || idle.as_mut().poll(cx).is_ready() {
                return Poll::Ready(Ok(()));
            }
            let mut buf = ReadBuf::new(&mut scratch);
            match Pin::new(&mut this.inner).poll_read(cx, &mut buf) {
                Poll::Ready(Ok(())) if !buf.filled().is_empty() => {
                    idle.as_mut().reset(tokio::time::Instant::now() + LINGER_IDLE);
                }
                // The client has closed (or reset) its side: nothing more to wait for.
                Poll::Ready(_) => return Poll::Ready(Ok(())),
                Poll::Pending => return Poll::Pending,
            }
        }
    }
}

/// The JSON answer for one of hyper's own answers to a request head it could not read (400,
/// 414, 431), or `None` for anything else.
///
/// hyper writes those itself, before any handler runs, as a bare head with
/// `content-length: 0`. Every answer from the app's handlers carries a body (errors are JSON,
/// see `server::finish_response`), so a bodiless 4xx head written in one piece is hyper's. The
/// socket is not vectored, so hyper flattens each answer into one buffer and the head arrives
/// whole in the first write.
fn replace_parse_error(buf: &[u8]) -> Option<Vec<u8>> {
    let rest = buf.strip_prefix(b"HTTP/1.1 4")?;
    let end = buf.windows(4).position(|w| w == b"\r\n\r\n")?;
    if end + 4 != buf.len() {
        return None;
    }
    let head = String::from_utf8_lossy(&buf[..end]).to_ascii_lowercase();
    if !head.lines().any(|l| l.trim() == "content-length: 0") {
        return None;
    }
    let (status, message) = match rest.get(..2)? {
        b"00" => (
            "400 Bad Request",
            "the request is not valid HTTP/1.1".to_string(),
        ),
        b"14" => (
            "414 URI Too Long",
            format!("the URL is too long (at most {MAX_URL_BYTES} bytes)"),
        ),
        // A URL longer than the whole head may be lands here too, so the message names both.
        b"31" => (
            "431 Request Header Fields Too Large",
            format!(
                "the request's URL and headers are too large (at most {MAX_HEAD_BYTES} bytes together, in at most {MAX_HEADERS} header lines; a URL at most {MAX_URL_BYTES} bytes)"
            ),
        ),
        _ => return None,
    };
    let body = serde_json::json!({ "error": message }).to_string();
    Some(
        format!(
            "HTTP/1.1 {status}\r\ncontent-type: application/json\r\ncontent-length: {}\r\nconnection: close\r\ncache-control: no-store\r\nx-content-type-options: nosniff\r\n\r\n{body}",
            body.len()
        )
        .into_bytes(),
    )
}

#[cfg(test)]
mod tests {
    use super::replace_parse_error;

    #[test]
    fn only_bodiless_parse_error_heads_are_replaced() {
        let hyper_431 = b"HTTP/1.1 431 Request Header Fields Too Large\r\ncontent-length: 0\r\ndate: x\r\n\r\n";
        let out = String::from_utf8(replace_parse_error(hyper_431).unwrap()).unwrap();
        assert!(out.starts_with("HTTP/1.1 431 "), "{out}");
        let (head, body) = out.split_once("\r\n\r\n").unwrap();
        assert!(head.contains(&format!("content-length: {}", body.len())));
        let v: serde_json::Value = serde_json::from_str(body).unwrap();
        assert!(v["error"].as_str().unwrap().contains("headers are too large"));
        // The app's own answers: a JSON error with its body, a success, a head split from its
        // body, a 404 without a body (never sent by the app, but not hyper's either).
        for other in [
            &b"HTTP/1.1 400 Bad Request\r\ncontent-type: application/json\r\ncontent-length: 13\r\n\r\n{\"error\":\"x\"}"[..],
            b"HTTP/1.1 200 OK\r\ncontent-length: 0\r\n\r\n",
            b"HTTP/1.1 431 Request Header Fields Too Large\r\ncontent-length: 5\r\n\r\n",
            b"HTTP/1.1 404 Not Found\r\ncontent-length: 0\r\n\r\n",
            b"{\"HTTP/1.1 400\"}",
        ] {
            assert!(replace_parse_error(other).is_none(), "{}", String::from_utf8_lossy(other));
        }
    }
}

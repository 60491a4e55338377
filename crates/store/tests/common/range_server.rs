//! A small HTTP/1.1 server on loopback for the remote-store tests: it serves one object by byte
//! ranges (with an ETag, honouring `If-Match`), and injects the faults a network and a server
//! can throw at a reader — stalls, connection resets, short bodies, 5xx and 4xx answers, the
//! object replaced between two requests. Plain threads and `std::net`, one connection each.

#![allow(dead_code)]

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// What the next requests get.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Fault {
    /// The next N requests get this status (e.g. 500, 503, 403, 404).
    Status(u16, usize),
    /// The next N requests are answered after a stall of this long.
    Stall(Duration, usize),
    /// The next N requests see their connection closed without an answer.
    Reset(usize),
    /// The next N answers send half the body, then close.
    Short(usize),
}

struct State {
    body: Vec<u8>,
    etag: u64,
    faults: Vec<Fault>,
}

pub struct RangeServer {
    pub port: u16,
    state: Arc<Mutex<State>>,
    stop: Arc<AtomicBool>,
    /// Requests answered (any status).
    pub requests: Arc<AtomicUsize>,
}

impl RangeServer {
    /// Serves `body` at every path.
    pub fn start(body: Vec<u8>) -> RangeServer {
        let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
        let port = listener.local_addr().expect("addr").port();
        let state = Arc::new(Mutex::new(State {
            body,
            etag: 1,
            faults: Vec::new(),
        }));
        let stop = Arc::new(AtomicBool::new(false));
        let requests = Arc::new(AtomicUsize::new(0));
        let (s, st, rq) = (state.clone(), stop.clone(), requests.clone());
        std::thread::spawn(move || {
            for conn in listener.incoming() {
                if st.load(Ordering::Relaxed) {
                    break;
                }
                let Ok(conn) = conn else { continue };
                let (s, rq) = (s.clone(), rq.clone());
                std::thread::spawn(move || serve(conn, &s, &rq));
            }
        });
        RangeServer {
            port,
            state,
            stop,
            requests,
        }
    }

    pub fn url(&self, path: &str) -> String {
        format!("http://127.0.0.1:{}/{path}", self.port)
    }

    pub fn inject(&self, fault: Fault) {
        self.state.lock().expect("state").faults.push(fault);
    }

    /// Forgets the faults not injected yet.
    pub fn replace_faults(&self) {
        self.state.lock().expect("state").faults.clear();
    }

    /// Replaces the object (a new ETag, as a server's would be).
    pub fn replace(&self, body: Vec<u8>) {
        let mut s = self.state.lock().expect("state");
        s.body = body;
        s.etag += 1;
    }
}

impl Drop for RangeServer {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        // Wake the accept loop.
        let _ = TcpStream::connect(("127.0.0.1", self.port));
    }
}

/// Takes the fault due for this request, if any.
fn next_fault(state: &Mutex<State>) -> Option<Fault> {
    let mut s = state.lock().ok()?;
    let f = *s.faults.first()?;
    let (left, fault) = match f {
        Fault::Status(code, n) => (n - 1, Fault::Status(code, n - 1)),
        Fault::Stall(d, n) => (n - 1, Fault::Stall(d, n - 1)),
        Fault::Reset(n) => (n - 1, Fault::Reset(n - 1)),
        Fault::Short(n) => (n - 1, Fault::Short(n - 1)),
    };
    if left == 0 {
        s.faults.remove(0);
    } else {
        s.faults[0] = fault;
    }
    Some(f)
}

fn serve(conn: TcpStream, state: &Mutex<State>, requests: &AtomicUsize) {
    let _ = conn.set_read_timeout(Some(Duration::from_secs(30)));
    let Ok(read_half) = conn.try_clone() else {
        return;
    };
    let mut reader = BufReader::new(read_half);
    let mut out = conn;
    loop {
        let mut line = String::new();
        if reader.read_line(&mut line).unwrap_or(0) == 0 {
            return;
        }
        let method = line.split_whitespace().next().unwrap_or("").to_string();
        let mut range = None;
        let mut if_match = None;
        let mut length = 0usize;
        loop {
            let mut h = String::new();
            if reader.read_line(&mut h).unwrap_or(0) == 0 {
                return;
            }
            let h = h.trim_end();
            if h.is_empty() {
                break;
            }
            if let Some((name, value)) = h.split_once(':') {
                let value = value.trim().to_string();
                match name.to_ascii_lowercase().as_str() {
                    "range" => range = Some(value),
                    "if-match" => if_match = Some(value),
                    "content-length" => length = value.parse().unwrap_or(0),
                    _ => {}
                }
            }
        }
        let mut discard = vec![0u8; length];
        let _ = reader.read_exact(&mut discard);
        requests.fetch_add(1, Ordering::Relaxed);
        let fault = next_fault(state);
        let (body, etag) = match state.lock() {
            Ok(s) => (s.body.clone(), s.etag),
            Err(_) => return,
        };
        let etag = format!("\"v{etag}\"");
        let respond = |out: &mut TcpStream, status: &str, headers: &str, payload: &[u8]| {
            let head = format!(
                "HTTP/1.1 {status}\r\nContent-Length: {}\r\nETag: {etag}\r\nAccept-Ranges: bytes\r\n{headers}\r\n",
                payload.len()
            );
            out.write_all(head.as_bytes())
                .and_then(|_| out.write_all(payload))
        };
        match fault {
            Some(Fault::Reset(_)) => return,
            Some(Fault::Stall(d, _)) => std::thread::sleep(d),
            Some(Fault::Status(code, _)) => {
                let status = format!("{code} Injected");
                if respond(&mut out, &status, "", b"injected").is_err() {
                    return;
                }
                continue;
            }
            _ => {}
        }
        if if_match.as_deref().is_some_and(|m| m != etag && m != "*") {
            if respond(&mut out, "412 Precondition Failed", "", b"").is_err() {
                return;
            }
            continue;
        }
        let total = body.len();
        let (start, end) = match range.as_deref().and_then(|r| parse_range(r, total)) {
            Some(r) => r,
            None => (0, total),
        };
        let status = if range.is_some() {
            "206 Partial Content"
        } else {
            "200 OK"
        };
        let headers = format!(
            "Content-Range: bytes {start}-{}/{total}\r\n",
            end.max(1) - 1
        );
        let payload = if method == "HEAD" {
            &[][..]
        } else {
            &body[start..end]
        };
        if let Some(Fault::Short(_)) = fault {
            let head = format!(
                "HTTP/1.1 {status}\r\nContent-Length: {}\r\nETag: {etag}\r\n{headers}\r\n",
                payload.len()
            );
            let _ = out.write_all(head.as_bytes());
            let _ = out.write_all(&payload[..payload.len() / 2]);
            return;
        }
        if respond(&mut out, status, &headers, payload).is_err() {
            return;
        }
    }
}

/// `bytes=a-b` / `bytes=a-` / `bytes=-n` as `start..end`.
fn parse_range(r: &str, total: usize) -> Option<(usize, usize)> {
    let spec = r.strip_prefix("bytes=")?;
    let (a, b) = spec.split_once('-')?;
    if a.is_empty() {
        let n: usize = b.parse().ok()?;
        return Some((total.saturating_sub(n), total));
    }
    let start: usize = a.parse().ok()?;
    let end = if b.is_empty() {
        total
    } else {
        (b.parse::<usize>().ok()? + 1).min(total)
    };
    (start < end).then_some((start, end))
}

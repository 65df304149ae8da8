//! What a silent, slow or greedy client can hold: the timeouts and the connection cap.
//!
//! Each test would hang without its limit; the outer `timeout` turns a hang into a failure
//! (it bounds the test, it measures nothing).

use crate::helpers::{configured, spawn_with};
use reqwest::Client;
use serde_json::{Value, json};
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpSocket, TcpStream};
use tokio::time::timeout;

const GUARD: Duration = Duration::from_secs(20);

/// Reads until the server closes the connection; what arrived before it did.
async fn read_to_close(stream: &mut TcpStream) -> Vec<u8> {
    let mut got = Vec::new();
    let mut buf = [0u8; 64 << 10];
    loop {
        match timeout(GUARD, stream.read(&mut buf)).await.expect("the server never closed the connection") {
            Ok(0) | Err(_) => return got,
            Ok(n) => got.extend_from_slice(&buf[..n]),
        }
    }
}

/// Polls `done` every 20 ms until it holds; failing with `what` if it never does.
async fn until<F: std::future::Future<Output = bool>>(what: &str, mut done: impl FnMut() -> F) {
    let poll = async {
        while !done().await {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    };
    timeout(GUARD, poll).await.unwrap_or_else(|_| panic!("{what}"));
}

/// A client that opens a new connection for every request, so that it holds none between them.
fn unpooled() -> Client {
    Client::builder().pool_max_idle_per_host(0).timeout(GUARD).build().unwrap()
}

#[tokio::test]
async fn idle_half_sent_and_kept_alive_connections_close_after_the_header_timeout() {
    let app = spawn_with(configured(|c| c.connections.header_timeout = Duration::from_millis(300))).await;
    let mut idle = TcpStream::connect(app.addr).await.unwrap();
    let mut half = TcpStream::connect(app.addr).await.unwrap();
    half.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\nX-Slow: ").await.unwrap();
    let mut kept = TcpStream::connect(app.addr).await.unwrap();
    kept.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n").await.unwrap();

    assert!(read_to_close(&mut idle).await.is_empty());
    assert!(!String::from_utf8_lossy(&read_to_close(&mut half).await).contains("200 OK"));
    // The keep-alive connection answered its request, then closed while idle.
    let answered = String::from_utf8(read_to_close(&mut kept).await).unwrap();
    assert!(answered.starts_with("HTTP/1.1 200 OK"), "{answered}");
    app.shutdown().await;
}

#[tokio::test]
async fn a_body_that_stops_arriving_gets_a_408_problem() {
    let app = spawn_with(configured(|c| c.body.timeout = Duration::from_millis(300))).await;
    let mut stream = TcpStream::connect(app.addr).await.unwrap();
    let head = "POST /v1/meshes HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: 1000\r\n\r\n";
    stream.write_all(head.as_bytes()).await.unwrap();
    stream.write_all(br#"{"function""#).await.unwrap();
    let response = String::from_utf8(read_to_close(&mut stream).await).unwrap();
    assert!(response.starts_with("HTTP/1.1 408"), "{response}");
    assert!(response.contains("application/problem+json"), "{response}");
    assert!(response.contains(r#""type":"/problems/body-timeout""#), "{response}");
    app.shutdown().await;
}

#[tokio::test]
async fn a_body_that_trickles_in_gets_a_408_once_past_the_timeout() {
    let app = spawn_with(configured(|c| c.body.timeout = Duration::from_millis(300))).await;
    let mut stream = TcpStream::connect(app.addr).await.unwrap();
    let head = "POST /v1/meshes HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: 1000\r\n\r\n";
    stream.write_all(head.as_bytes()).await.unwrap();
    // Ten bytes every 50 ms never pause for the timeout; the whole body would take 5 s. The
    // answer is read as it comes, and the trickle stops there.
    let (mut reader, mut writer) = stream.split();
    let trickle = async {
        for _ in 0..100 {
            if writer.write_all(b"          ").await.is_err() {
                break;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        std::future::pending::<()>().await;
    };
    let mut first = vec![0u8; 4096];
    let n = tokio::select! {
        read = timeout(GUARD, reader.read(&mut first)) => read.expect("no answer").unwrap(),
        () = trickle => unreachable!(),
    };
    let response = String::from_utf8_lossy(&first[..n]).into_owned();
    assert!(response.starts_with("HTTP/1.1 408"), "{response}");
    app.shutdown().await;
}

#[tokio::test]
async fn a_client_that_stops_reading_is_dropped_with_its_response() {
    let config = configured(|c| c.connections.write_timeout = Duration::from_millis(300));
    let app = spawn_with(config).await;
    // A mesh far larger than the socket buffers on both sides.
    let request = json!({"function": "sin(9*x)*cos(7*y)", "max_vertices": 300_000, "criterion": "variation"});
    let client = unpooled();
    let response = client.post(app.url("/v1/meshes")).json(&request).send().await.unwrap();
    assert_eq!(response.status(), 200);
    let document = response.bytes().await.unwrap();
    let id = serde_json::from_slice::<Value>(&document).unwrap()["id"].as_str().unwrap().to_owned();
    let full = document.len();

    let socket = TcpSocket::new_v4().unwrap();
    socket.set_recv_buffer_size(4096).unwrap();
    let mut stalled = socket.connect(app.addr).await.unwrap();
    let get = format!("GET /v1/jobs/{id}/mesh HTTP/1.1\r\nHost: x\r\n\r\n");
    stalled.write_all(get.as_bytes()).await.unwrap();

    // The server counts the stalled connection until its write timeout drops it; then only
    // the connection asking for the metrics is open.
    let metrics = app.url("/metrics");
    let open = || async {
        let text = client.get(&metrics).send().await.unwrap().text().await.unwrap();
        let line = text.lines().find(|l| l.starts_with("meshfit_connections_open ")).unwrap().to_owned();
        line.rsplit(' ').next().unwrap().parse::<u64>().unwrap()
    };
    assert_eq!(open().await, 2, "the stalled connection is open while it could still read");
    until("the stalled reader was never dropped", || async { open().await == 1 }).await;
    let received = read_to_close(&mut stalled).await.len();
    assert!(received < full, "received {received} of {full} bytes: the response was not cut short");
    app.shutdown().await;
}

#[tokio::test]
async fn bodies_and_jobs_are_charged_to_the_memory_budget_before_they_are_taken() {
    let config = configured(|c| {
        c.pool.memory_bytes = 64 << 20;
        c.cache.memory_bytes = 8 << 20;
        c.body.max_bytes = 100 << 20;
    });
    let app = spawn_with(config).await;
    // A job whose vertex budget cannot fit is refused before it runs.
    let big = app.post("/v1/jobs", &json!({"function": "x*y", "max_vertices": 1_000_000})).await;
    assert_eq!(big.status(), 503);
    assert!(big.headers()["retry-after"].to_str().unwrap().parse::<u64>().unwrap() >= 1);
    assert_eq!(big.json::<Value>().await.unwrap()["type"], "/problems/over-memory-budget");
    assert_eq!(app.metric("meshfit_engine_runs_total").await, 0.0);

    // A body is charged by its declared length while it is read; a second one that does
    // not fit is refused before a byte of it is read.
    let mut slow = TcpStream::connect(app.addr).await.unwrap();
    let head = format!(
        "POST /v1/meshes HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n{{",
        40 << 20
    );
    slow.write_all(head.as_bytes()).await.unwrap();
    until("the body being read was never charged", || async {
        app.metric("meshfit_memory_charged_bytes").await == (40 << 20) as f64
    })
    .await;
    let mut second = TcpStream::connect(app.addr).await.unwrap();
    second.write_all(head.as_bytes()).await.unwrap();
    let refused = String::from_utf8(read_to_close(&mut second).await).unwrap();
    assert!(refused.starts_with("HTTP/1.1 503"), "{refused}");
    assert!(refused.contains("/problems/over-memory-budget"), "{refused}");
    assert_eq!(app.metric("meshfit_memory_refusals_total").await, 2.0);

    drop(slow);
    until("an abandoned body's charge was never returned", || async {
        app.metric("meshfit_memory_charged_bytes").await == 0.0
    })
    .await;
    let small = app.post("/v1/meshes", &json!({"function": "x*y", "max_vertices": 1000})).await;
    assert_eq!(small.status(), 200);
    app.shutdown().await;
}

/// A connection with a request in flight: its headers promise a body that never comes. The
/// server's `100 Continue`, sent when the handler starts reading the body, says it is in flight.
async fn busy(addr: std::net::SocketAddr) -> TcpStream {
    let mut stream = TcpStream::connect(addr).await.unwrap();
    let head = "POST /v1/meshes HTTP/1.1\r\nhost: x\r\ncontent-type: application/json\r\n\
                content-length: 100\r\nexpect: 100-continue\r\n\r\n";
    stream.write_all(head.as_bytes()).await.unwrap();
    let mut got = Vec::new();
    let mut buf = [0u8; 256];
    while !got.ends_with(b"\r\n\r\n") {
        let n = timeout(GUARD, stream.read(&mut buf)).await.expect("no 100 Continue").unwrap();
        assert!(n > 0, "closed before 100 Continue: {}", String::from_utf8_lossy(&got));
        got.extend_from_slice(&buf[..n]);
    }
    assert!(got.starts_with(b"HTTP/1.1 100 Continue"), "{}", String::from_utf8_lossy(&got));
    stream
}

#[tokio::test]
async fn past_the_connection_cap_of_busy_connections_healthz_answers_and_other_routes_get_503() {
    let app = spawn_with(configured(|c| c.connections.max = 4)).await;
    let mut held = Vec::new();
    for _ in 0..4 {
        held.push(busy(app.addr).await);
    }
    let client = unpooled();
    let health = client.get(app.url("/healthz")).send().await.unwrap();
    assert_eq!(health.status(), 200);
    let refused = client.get(app.url("/v1/jobs/0123")).send().await.unwrap();
    assert_eq!(refused.status(), 503);
    assert_eq!(refused.headers()["retry-after"], "1");
    let problem: Value = refused.json().await.unwrap();
    assert_eq!(problem["type"], "/problems/too-many-connections");

    drop(held);
    until("connections freed by their clients were never counted as closed", || async {
        client.get(app.url("/v1/jobs/0123")).send().await.unwrap().status() == 404
    })
    .await;
    assert!(app.metric("meshfit_connections_refused_total").await >= 2.0);
    app.shutdown().await;
}

#[tokio::test]
async fn at_the_cap_an_idle_flood_gives_way_oldest_first_to_healthz_and_real_requests() {
    let app = spawn_with(configured(|c| c.connections.max = 4)).await;
    let mut idle = Vec::new();
    for _ in 0..12 {
        idle.push(TcpStream::connect(app.addr).await.unwrap());
    }
    let client = unpooled();
    for _ in 0..3 {
        assert_eq!(client.get(app.url("/healthz")).send().await.unwrap().status(), 200);
        let body = json!({"function": "x*y", "max_vertices": 100});
        let mesh = client.post(app.url("/v1/meshes")).json(&body).send().await.unwrap();
        assert_eq!(mesh.status(), 200);
    }
    // The first eight gave way to the last four, without a byte, well before the header
    // timeout (30 s, past the guard); then the requests took the places of the next ones.
    for stream in &mut idle[..8] {
        assert!(read_to_close(stream).await.is_empty());
    }
    assert_eq!(app.metric("meshfit_connections_refused_total").await, 0.0, "none was refused");
    app.shutdown().await;
}

#[tokio::test]
async fn at_the_cap_a_slow_reader_keeps_its_whole_response_while_idle_connections_give_way() {
    let app = spawn_with(configured(|c| c.connections.max = 2)).await;
    let client = unpooled();
    let request = json!({"function": "sin(9*x)*cos(7*y)", "max_vertices": 20_000, "criterion": "variation"});
    let document =
        client.post(app.url("/v1/meshes")).json(&request).send().await.unwrap().bytes().await.unwrap();
    let id = serde_json::from_slice::<Value>(&document).unwrap()["id"].as_str().unwrap().to_owned();

    // A reader with a small buffer that reads nothing until the flood is over.
    let socket = TcpSocket::new_v4().unwrap();
    socket.set_recv_buffer_size(4096).unwrap();
    let mut slow = socket.connect(app.addr).await.unwrap();
    let get = format!("GET /v1/jobs/{id}/mesh HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
    slow.write_all(get.as_bytes()).await.unwrap();
    let mut idle = Vec::new();
    for _ in 0..6 {
        idle.push(TcpStream::connect(app.addr).await.unwrap());
    }
    assert_eq!(client.get(app.url("/healthz")).send().await.unwrap().status(), 200);

    let received = read_to_close(&mut slow).await;
    let head_end = received.windows(4).position(|w| w == b"\r\n\r\n").unwrap() + 4;
    assert!(received.starts_with(b"HTTP/1.1 200"), "{}", String::from_utf8_lossy(&received[..head_end]));
    let body = dechunk(&received[head_end..]);
    assert!(body == document[..], "{} of {} bytes", body.len(), document.len());
    app.shutdown().await;
}

/// A chunked body's data; panics on a body cut short.
fn dechunk(mut chunked: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    loop {
        let line_end = chunked.windows(2).position(|w| w == b"\r\n").expect("a chunk size line");
        let size = usize::from_str_radix(std::str::from_utf8(&chunked[..line_end]).unwrap(), 16).unwrap();
        chunked = &chunked[line_end + 2..];
        if size == 0 {
            return out;
        }
        out.extend_from_slice(&chunked[..size]);
        chunked = &chunked[size + 2..];
    }
}

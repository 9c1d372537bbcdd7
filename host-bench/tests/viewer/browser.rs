//! The bench page in a real headless Chromium, driven over the DevTools protocol, during a
//! paced `emulate --live`.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use tungstenite::Message;

use super::start_live;

/// A small HTTP GET: the body, by its Content-Length (Chromium's DevTools endpoint keeps the
/// connection open), else to the end (the live server's `/history` closes it).
pub fn http_get(port: u16, path: &str) -> std::io::Result<String> {
    let s = TcpStream::connect(("127.0.0.1", port))?;
    s.set_read_timeout(Some(Duration::from_secs(5)))?;
    write!(&s, "GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n")?;
    let mut r = BufReader::new(s);
    let mut len = None;
    loop {
        let mut line = String::new();
        r.read_line(&mut line)?;
        let line = line.trim_end();
        if line.is_empty() {
            break;
        }
        if let Some(v) = line.to_ascii_lowercase().strip_prefix("content-length:") {
            len = v.trim().parse().ok();
        }
    }
    let mut body = Vec::new();
    match len {
        Some(n) => {
            body.resize(n, 0);
            r.read_exact(&mut body)?;
        }
        None => {
            r.read_to_end(&mut body)?;
        }
    }
    Ok(String::from_utf8_lossy(&body).into_owned())
}

/// Chromium on the bench page, driven over the DevTools protocol.
struct Browser {
    child: Child,
    ws: tungstenite::WebSocket<tungstenite::stream::MaybeTlsStream<TcpStream>>,
    id: u64,
    _profile: tempfile::TempDir,
}

impl Browser {
    /// `Ok(None)`: there is no Chromium here.
    fn open(url: &str) -> Result<Option<Browser>, String> {
        let Some(chromium) = ["chromium", "chromium-browser", "google-chrome"]
            .into_iter()
            .find(|c| Command::new(c).arg("--version").output().is_ok())
        else {
            return Ok(None);
        };
        let profile = tempfile::tempdir().unwrap();
        let mut child = Command::new(chromium)
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-quic",
                "--no-first-run",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--window-size=1280,900",
                "--remote-debugging-port=0",
            ])
            .arg(format!("--user-data-dir={}", profile.path().display()))
            .arg(url)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| format!("{chromium}: {e}"))?;
        let mut lines = BufReader::new(child.stderr.take().unwrap()).lines();
        let port: u16 = loop {
            let Some(Ok(line)) = lines.next() else {
                return Err(format!("{chromium} ended without its DevTools address"));
            };
            if let Some(rest) = line.split("ws://127.0.0.1:").nth(1) {
                break rest
                    .split('/')
                    .next()
                    .and_then(|p| p.parse().ok())
                    .ok_or(line)?;
            }
        };
        std::thread::spawn(move || lines.for_each(drop));
        // The page's target appears once Chromium has opened it.
        let deadline = Instant::now() + Duration::from_secs(10);
        let page = loop {
            let list = http_get(port, "/json/list").unwrap_or_else(|e| e.to_string());
            let targets: serde_json::Value = serde_json::from_str(&list).unwrap_or_default();
            let found = (targets.as_array().into_iter().flatten())
                .find(|t| {
                    t["type"] == "page" && t["url"].as_str().is_some_and(|u| u.starts_with("http"))
                })
                .and_then(|t| t["webSocketDebuggerUrl"].as_str().map(str::to_string));
            match found {
                Some(p) => break p,
                None if Instant::now() > deadline => return Err(format!("no page target: {list}")),
                None => std::thread::sleep(Duration::from_millis(100)),
            }
        };
        let (ws, _) = tungstenite::connect(&page).map_err(|e| format!("{page}: {e}"))?;
        Ok(Some(Browser {
            child,
            ws,
            id: 0,
            _profile: profile,
        }))
    }

    fn call(&mut self, method: &str, params: serde_json::Value) -> serde_json::Value {
        self.id += 1;
        let id = self.id;
        self.ws
            .send(Message::text(
                serde_json::json!({"id": id, "method": method, "params": params}).to_string(),
            ))
            .unwrap();
        loop {
            if let Message::Text(t) = self.ws.read().unwrap() {
                let v: serde_json::Value = serde_json::from_str(t.as_str()).unwrap();
                if v["id"] == id {
                    return v["result"].clone();
                }
            }
        }
    }

    /// An expression's value in the page, as JSON.
    fn eval(&mut self, expr: &str) -> serde_json::Value {
        let r = self.call(
            "Runtime.evaluate",
            serde_json::json!({"expression": format!("JSON.stringify({expr})"), "returnByValue": true}),
        );
        serde_json::from_str(r["result"]["value"].as_str().unwrap_or("null")).unwrap()
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// What the page shows: run time and message count on screen, points per path, coloured
/// pixels on the field (the paths; the grid is grey, the truth black).
const PAGE_STATE: &str = r#"{
  shown_t: parseFloat(document.getElementById('t').textContent),
  shown_count: parseInt(document.getElementById('count').textContent),
  conn: document.getElementById('conn').textContent,
  paths: Object.fromEntries(Object.entries(bench.paths).map(([k, v]) => [k, v.length])),
  rows: document.querySelectorAll('#numbers tr').length,
  inked: (() => { const c = document.getElementById('field');
    const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
    let n = 0; for (let i = 0; i < d.length; i += 4)
      if (d[i+3] > 0 && Math.max(d[i], d[i+1], d[i+2]) - Math.min(d[i], d[i+1], d[i+2]) > 80) n++;
    return n; })()
}"#;

#[test]
fn the_bench_page_draws_the_run_in_a_headless_browser() {
    let required = std::env::var("OMNIBENCH_BROWSER_TEST").is_ok_and(|v| v == "require");
    let (mut run, port) = start_live(&[
        "emulate",
        "--duration",
        "6",
        "--live-speed",
        "1",
        "--live-hold",
        "5",
    ]);
    let opened = Browser::open(&format!("http://127.0.0.1:{port}/"));
    let Some(mut browser) = opened.unwrap_or_else(|e| panic!("Chromium: {e}")) else {
        let _ = run.kill();
        assert!(!required, "no Chromium: the bench page was not tested");
        eprintln!("skipped: no Chromium here (.ci/run installs it and requires this test)");
        return;
    };
    std::thread::sleep(Duration::from_millis(2000));
    let early = browser.eval(PAGE_STATE);
    std::thread::sleep(Duration::from_millis(2000));
    let later = browser.eval(PAGE_STATE);
    let shot = browser.call(
        "Page.captureScreenshot",
        serde_json::json!({"format": "png"}),
    );
    let _ = run.kill();
    let _ = run.wait();
    eprintln!("the page at 2 s: {early}\nthe page at 4 s: {later}");
    assert_eq!(later["conn"], "open");
    // The numbers on screen advance while the run plays.
    let num = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap_or(0.0);
    assert!(num(&early, "shown_t") > 0.5, "{early}");
    assert!(
        num(&later, "shown_t") > num(&early, "shown_t") + 1.0,
        "{later}"
    );
    assert!(num(&later, "shown_count") > num(&early, "shown_count"));
    // The true and estimated paths are drawn as they grow.
    for p in ["/truth/pose", "/slave/pose", "/master/estimate"] {
        let (a, b) = (early["paths"][p].as_u64(), later["paths"][p].as_u64());
        assert!(a.unwrap_or(0) > 10 && b > a, "{p}: {a:?} then {b:?}");
    }
    // ... in colour on the field, more of them as the run goes.
    assert!(
        num(&early, "inked") > 300.0,
        "no path on the field: {early}"
    );
    assert!(
        num(&later, "inked") > num(&early, "inked") + 300.0,
        "the paths stopped: {later}"
    );
    assert!(num(&later, "rows") >= 3.0, "the numbers table: {later}");
    // Kept for a person to look at (.ci/run copies it beside its log).
    let png = base64::Engine::decode(
        &base64::engine::general_purpose::STANDARD,
        shot["data"].as_str().unwrap(),
    )
    .unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let path = Path::new(env!("CARGO_TARGET_TMPDIR")).join("bench-page.png");
    std::fs::write(&path, png).unwrap();
    eprintln!("screenshot: {}", path.display());
}

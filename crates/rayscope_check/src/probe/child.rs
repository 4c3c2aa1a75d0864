//! The probed program as a child process: one request line out, one answer line back, the two
//! together within a time limit, so a program that hangs, crashes, stops reading or floods its
//! output never hangs rayscope nor grows its memory.
//!
//! Each pipe has a thread of its own: a writer (a program that stops reading blocks it, not
//! rayscope), a reader of answer lines (each at most [`MAX_LINE`] bytes, a few read ahead at most)
//! and a reader of stderr that keeps its last [`STDERR_KEPT`] bytes.

use std::io::{BufRead, BufReader, Read, Write};
use std::process::{Child, ChildStdin, Command, ExitStatus, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender, SyncSender};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

/// Longest answer line accepted; anything longer is not an answer.
pub const MAX_LINE: usize = 64 * 1024;

/// Bytes of the end of the program's stderr kept to show when it fails; what came before is
/// counted, not kept.
pub const STDERR_KEPT: usize = 64 * 1024;

/// Lines of the kept stderr shown, and characters of each.
const STDERR_LINES: usize = 15;
const STDERR_LINE_CHARS: usize = 300;

/// Answer lines read from the program before rayscope asks for them; past these the reader
/// waits, so a program printing without end fills its pipe, not rayscope's memory.
const LINES_AHEAD: usize = 4;

/// How long a program that closed a pipe gets to exit before it is described as still running.
const EXIT_GRACE: Duration = Duration::from_secs(1);

/// A line read from the program's stdout, or why none came.
enum Line {
    Text(String),
    TooLong,
    Failed(std::io::Error),
}

/// Why no answer came back.
#[derive(Debug)]
pub enum ChildError {
    /// No answer within the time limit.
    Timeout(Duration),
    /// The program did not take the request from its input within the time limit: it stopped
    /// reading.
    NotReading(Duration),
    /// The program closed its output (stdout), or exited; its exit status when it had one.
    Exited(Option<ExitStatus>),
    /// The program closed its input (stdin) and had not exited.
    InputClosed,
    /// A line longer than [`MAX_LINE`] bytes.
    TooLong,
    /// Reading or writing the pipes failed.
    Io(std::io::Error),
}

/// The end of what the program wrote to stderr.
#[derive(Debug, Default)]
struct StderrTail {
    /// The last [`STDERR_KEPT`] bytes at most (up to twice that between trims).
    kept: Vec<u8>,
    /// Bytes written in all.
    total: u64,
}

impl StderrTail {
    fn push(&mut self, chunk: &[u8]) {
        self.total += chunk.len() as u64;
        self.kept.extend_from_slice(chunk);
        if self.kept.len() > 2 * STDERR_KEPT {
            let cut = self.kept.len() - STDERR_KEPT;
            self.kept.drain(..cut);
        }
    }
}

/// What the program wrote to stderr, as shown in an error.
#[derive(Debug, Clone, PartialEq)]
pub struct Stderr {
    /// Its last lines (at most `STDERR_LINES`, each cut to `STDERR_LINE_CHARS` characters,
    /// control characters replaced).
    pub lines: Vec<String>,
    /// Bytes it wrote in all.
    pub total: u64,
    /// Bytes of the start not kept (those before the last [`STDERR_KEPT`]).
    pub dropped: u64,
}

/// The running program.
pub struct Probed {
    child: Child,
    /// Request lines to the writer thread; `None` once the program's input is closed.
    requests: Option<Sender<String>>,
    /// One result per request line written.
    written: Receiver<std::io::Result<()>>,
    lines: Receiver<Line>,
    stderr: Arc<Mutex<StderrTail>>,
    stderr_done: Receiver<()>,
}

impl Probed {
    /// Starts `command` (program and arguments) with piped stdin, stdout and stderr, in a
    /// process group of its own.
    pub fn spawn(command: &[String]) -> std::io::Result<Self> {
        let (program, args) = command
            .split_first()
            .ok_or_else(|| std::io::Error::new(std::io::ErrorKind::InvalidInput, "no command given"))?;
        let mut cmd = Command::new(program);
        cmd.args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        #[cfg(unix)]
        {
            // A group of its own, so that stopping it also stops what it started (`dotnet run`
            // runs the program as a grandchild).
            use std::os::unix::process::CommandExt;
            cmd.process_group(0);
        }
        let mut child = cmd.spawn()?;
        let (Some(stdin), Some(stdout), Some(stderr)) = (child.stdin.take(), child.stdout.take(), child.stderr.take())
        else {
            kill_group(child.id());
            let _ = child.kill();
            let _ = child.wait();
            return Err(std::io::Error::other("the program's pipes were not opened"));
        };
        let (requests, to_write) = mpsc::channel();
        let (written_tx, written) = mpsc::channel();
        thread::spawn(move || write_lines(stdin, &to_write, &written_tx));
        let (tx, lines) = mpsc::sync_channel(LINES_AHEAD);
        thread::spawn(move || read_lines(stdout, &tx));
        let tail = Arc::new(Mutex::new(StderrTail::default()));
        let (done_tx, stderr_done) = mpsc::channel();
        {
            let tail = tail.clone();
            thread::spawn(move || {
                read_stderr(stderr, &tail);
                let _ = done_tx.send(());
            });
        }
        Ok(Self {
            child,
            requests: Some(requests),
            written,
            lines,
            stderr: tail,
            stderr_done,
        })
    }

    /// Writes `request` as one line and waits for one line back, both within `timeout`.
    pub fn ask(&mut self, request: &str, timeout: Duration) -> Result<String, ChildError> {
        let start = Instant::now();
        let sent = self
            .requests
            .as_ref()
            .is_some_and(|r| r.send(format!("{request}\n")).is_ok());
        if !sent {
            return Err(self.input_closed());
        }
        match self.written.recv_timeout(timeout) {
            Ok(Ok(())) => {}
            Ok(Err(e)) if e.kind() == std::io::ErrorKind::BrokenPipe => return Err(self.input_closed()),
            Ok(Err(e)) => return Err(ChildError::Io(e)),
            Err(RecvTimeoutError::Timeout) => return Err(ChildError::NotReading(timeout)),
            Err(RecvTimeoutError::Disconnected) => return Err(self.input_closed()),
        }
        match self.lines.recv_timeout(timeout.saturating_sub(start.elapsed())) {
            Ok(Line::Text(s)) => Ok(s),
            Ok(Line::TooLong) => Err(ChildError::TooLong),
            Ok(Line::Failed(e)) => Err(ChildError::Io(e)),
            Err(RecvTimeoutError::Timeout) => Err(ChildError::Timeout(timeout)),
            Err(RecvTimeoutError::Disconnected) => Err(ChildError::Exited(self.exit_status(EXIT_GRACE))),
        }
    }

    /// Why a request could not be written: the program exited, or only closed its input.
    fn input_closed(&mut self) -> ChildError {
        self.requests = None;
        match self.exit_status(EXIT_GRACE) {
            Some(s) => ChildError::Exited(Some(s)),
            None => ChildError::InputClosed,
        }
    }

    /// The exit status, waiting up to `wait` for the program to end.
    fn exit_status(&mut self, wait: Duration) -> Option<ExitStatus> {
        let start = Instant::now();
        loop {
            match self.child.try_wait() {
                Ok(Some(s)) => return Some(s),
                Ok(None) if start.elapsed() < wait => thread::sleep(Duration::from_millis(10)),
                _ => return None,
            }
        }
    }

    /// What the program wrote to stderr: its last lines, and how much it wrote.
    pub fn stderr(&self) -> Stderr {
        // Let the reader catch up with what a crashed program wrote last.
        let _ = self.stderr_done.recv_timeout(Duration::from_millis(300));
        let tail = self.stderr.lock().unwrap_or_else(|e| e.into_inner());
        let start = tail.kept.len().saturating_sub(STDERR_KEPT);
        let kept = &tail.kept[start..];
        let text = String::from_utf8_lossy(kept);
        let mut lines: Vec<&str> = text.lines().collect();
        while lines.last().is_some_and(|l| l.trim().is_empty()) {
            lines.pop();
        }
        let first = lines.len().saturating_sub(STDERR_LINES);
        Stderr {
            lines: lines[first..].iter().map(|l| shown_line(l)).collect(),
            total: tail.total,
            dropped: tail.total - kept.len() as u64,
        }
    }

    /// Closes the program's input (the signal to exit), stops it if it has not exited within
    /// `grace`, and stops whatever it started that is still running.
    pub fn finish(&mut self, grace: Duration) {
        self.requests = None;
        if self.exit_status(grace).is_none() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
        kill_group(self.child.id());
    }

    /// The program's process id (on Unix also its process group's).
    pub fn id(&self) -> u32 {
        self.child.id()
    }

    /// Stops the program and its process group now.
    pub fn kill(&mut self) {
        kill_group(self.child.id());
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for Probed {
    fn drop(&mut self) {
        // Whatever it started too, even when the program itself has exited.
        self.kill();
    }
}

/// Stops the process group `pid` leads (what [`Probed::spawn`] started), where there are groups.
pub fn kill_group(pid: u32) {
    #[cfg(unix)]
    {
        if let Ok(pid) = i32::try_from(pid) {
            let _ = nix::sys::signal::killpg(nix::unistd::Pid::from_raw(pid), nix::sys::signal::Signal::SIGKILL);
        }
    }
    #[cfg(not(unix))]
    let _ = pid;
}

/// A line of stderr as shown: cut, with control characters (a terminal's escape sequences)
/// replaced.
fn shown_line(l: &str) -> String {
    let mut s: String = l
        .trim_end()
        .chars()
        .take(STDERR_LINE_CHARS)
        .map(|c| if c.is_control() && c != '\t' { '\u{fffd}' } else { c })
        .collect();
    if l.trim_end().chars().nth(STDERR_LINE_CHARS).is_some() {
        s.push_str(" …");
    }
    s
}

/// Writes each request line to the program's input, answering each with the write's result;
/// stops at the first failure, and closes the input when no more requests come.
fn write_lines(mut stdin: ChildStdin, requests: &Receiver<String>, written: &Sender<std::io::Result<()>>) {
    for line in requests {
        let result = stdin.write_all(line.as_bytes()).and_then(|()| stdin.flush());
        let failed = result.is_err();
        if written.send(result).is_err() || failed {
            return;
        }
    }
}

/// Keeps the end of `err` in `tail` until it closes.
fn read_stderr(mut err: impl Read, tail: &Mutex<StderrTail>) {
    let mut buf = vec![0u8; 16 * 1024];
    loop {
        match err.read(&mut buf) {
            Ok(0) => return,
            Ok(n) => tail.lock().unwrap_or_else(|e| e.into_inner()).push(&buf[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(_) => return,
        }
    }
}

/// Sends each line of `out` to `tx`, stopping at the end, at an error or at an overlong line.
fn read_lines(out: impl Read, tx: &SyncSender<Line>) {
    let mut r = BufReader::new(out);
    let mut buf: Vec<u8> = Vec::new();
    loop {
        let chunk = match r.fill_buf() {
            Ok([]) => {
                if !buf.is_empty() {
                    let _ = tx.send(Line::Text(String::from_utf8_lossy(&buf).into_owned()));
                }
                return;
            }
            Ok(c) => c,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => {
                let _ = tx.send(Line::Failed(e));
                return;
            }
        };
        if let Some(i) = chunk.iter().position(|b| *b == b'\n') {
            buf.extend_from_slice(&chunk[..i]);
            r.consume(i + 1);
            if buf.last() == Some(&b'\r') {
                buf.pop();
            }
            let line = String::from_utf8_lossy(&buf).into_owned();
            buf.clear();
            if tx.send(Line::Text(line)).is_err() {
                return;
            }
        } else {
            let n = chunk.len();
            buf.extend_from_slice(chunk);
            r.consume(n);
        }
        if buf.len() > MAX_LINE {
            let _ = tx.send(Line::TooLong);
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stderr_tail_keeps_the_end_and_counts_the_rest() {
        let mut t = StderrTail::default();
        for _ in 0..1000 {
            t.push(&[b'x'; 1000]);
        }
        t.push(b"\nlast line\n");
        assert!(t.kept.len() <= 2 * STDERR_KEPT);
        assert_eq!(t.total, 1_000_011);
        assert!(t.kept.ends_with(b"x\nlast line\n"));
    }

    #[test]
    fn shown_lines_are_cut_and_harmless() {
        assert_eq!(shown_line("a\u{1b}[31mb  "), "a\u{fffd}[31mb");
        let long = shown_line(&"y".repeat(1000));
        assert_eq!(long.chars().count(), STDERR_LINE_CHARS + 2);
        assert!(long.ends_with(" …"));
    }
}

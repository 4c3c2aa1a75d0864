//! The probed program as a child process: one request line out, one answer line back, each
//! within a time limit, so a program that hangs, crashes or floods its output never hangs
//! rayscope.

use std::collections::VecDeque;
use std::io::{BufRead, BufReader, Read, Write};
use std::process::{Child, ChildStdin, Command, ExitStatus, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

/// Longest answer line accepted; anything longer is not an answer.
const MAX_LINE: usize = 64 * 1024;

/// Lines of the program's stderr kept to show when it fails.
const STDERR_LINES: usize = 15;

/// A line read from the program's stdout, or why none came.
enum Line {
    Text(String),
    TooLong,
    Failed(std::io::Error),
}

/// Why no answer came back.
#[derive(Debug)]
pub enum ChildError {
    /// Nothing within the time limit.
    Timeout(Duration),
    /// The program closed its output or exited; its exit status when it had one.
    Exited(Option<ExitStatus>),
    /// A line longer than [`MAX_LINE`] bytes.
    TooLong,
    /// Reading or writing the pipes failed.
    Io(std::io::Error),
}

/// The running program.
pub struct Probed {
    child: Child,
    stdin: Option<ChildStdin>,
    lines: Receiver<Line>,
    stderr: Arc<Mutex<VecDeque<String>>>,
    stderr_done: Receiver<()>,
}

impl Probed {
    /// Starts `command` (program and arguments) with piped stdin, stdout and stderr.
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
        let stdin = child.stdin.take();
        let stdout = child.stdout.take().expect("stdout is piped");
        let stderr = child.stderr.take().expect("stderr is piped");
        let (tx, lines) = mpsc::channel();
        thread::spawn(move || read_lines(stdout, &tx));
        let tail = Arc::new(Mutex::new(VecDeque::new()));
        let (done_tx, stderr_done) = mpsc::channel();
        {
            let tail = tail.clone();
            thread::spawn(move || {
                let mut r = BufReader::new(stderr);
                let mut buf = Vec::new();
                loop {
                    buf.clear();
                    match r.read_until(b'\n', &mut buf) {
                        Ok(0) | Err(_) => break,
                        Ok(_) => {
                            let mut s = String::from_utf8_lossy(&buf).trim_end().to_string();
                            if s.len() > 300 {
                                let cut = (0..=300).rev().find(|i| s.is_char_boundary(*i)).unwrap_or(0);
                                s.truncate(cut);
                                s.push_str(" …");
                            }
                            let mut t = tail.lock().unwrap_or_else(|e| e.into_inner());
                            if t.len() == STDERR_LINES {
                                t.pop_front();
                            }
                            t.push_back(s);
                        }
                    }
                }
                let _ = done_tx.send(());
            });
        }
        Ok(Self {
            child,
            stdin,
            lines,
            stderr: tail,
            stderr_done,
        })
    }

    /// Writes `request` as one line and waits up to `timeout` for one line back.
    pub fn ask(&mut self, request: &str, timeout: Duration) -> Result<String, ChildError> {
        let Some(stdin) = self.stdin.as_mut() else {
            return Err(ChildError::Exited(None));
        };
        let written = stdin
            .write_all(request.as_bytes())
            .and_then(|()| stdin.write_all(b"\n"))
            .and_then(|()| stdin.flush());
        if let Err(e) = written {
            // A closed pipe means the program has gone: report how it ended.
            if e.kind() == std::io::ErrorKind::BrokenPipe {
                return Err(ChildError::Exited(self.exit_status(Duration::from_secs(2))));
            }
            return Err(ChildError::Io(e));
        }
        self.read(timeout)
    }

    /// Waits up to `timeout` for one line.
    pub fn read(&mut self, timeout: Duration) -> Result<String, ChildError> {
        match self.lines.recv_timeout(timeout) {
            Ok(Line::Text(s)) => Ok(s),
            Ok(Line::TooLong) => Err(ChildError::TooLong),
            Ok(Line::Failed(e)) => Err(ChildError::Io(e)),
            Err(RecvTimeoutError::Timeout) => Err(ChildError::Timeout(timeout)),
            Err(RecvTimeoutError::Disconnected) => Err(ChildError::Exited(self.exit_status(Duration::from_secs(2)))),
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

    /// The last lines the program wrote to stderr.
    pub fn stderr_tail(&self) -> Vec<String> {
        // Let the reader catch up with what a crashed program wrote last.
        let _ = self.stderr_done.recv_timeout(Duration::from_millis(300));
        self.stderr
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .iter()
            .cloned()
            .collect()
    }

    /// Closes the program's input (the signal to exit) and stops it if it has not exited within
    /// `grace`.
    pub fn finish(&mut self, grace: Duration) {
        self.stdin = None;
        if self.exit_status(grace).is_none() {
            self.kill();
        }
    }

    /// The program's process id (on Unix also its process group's).
    pub fn id(&self) -> u32 {
        self.child.id()
    }

    /// Stops the program (and its process group) now.
    pub fn kill(&mut self) {
        kill_group(self.child.id());
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for Probed {
    fn drop(&mut self) {
        if matches!(self.child.try_wait(), Ok(None)) {
            self.kill();
        }
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

/// Sends each line of `out` to `tx`, stopping at the end, at an error or at an overlong line.
fn read_lines(out: impl Read, tx: &mpsc::Sender<Line>) {
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

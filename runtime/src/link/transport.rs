//! Byte transports under a controller protocol: TCP, serial, and an in-memory pipe for the
//! in-process simulator. A transport moves bytes and knows nothing of lines or protocols.

use super::LinkError;
use std::io::{self, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, channel};
use std::time::Duration;

/// A full-duplex byte stream with a timed read.
pub trait Transport: Send {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()>;
    /// Reads what has arrived, waiting at most `timeout`; `Ok(0)` when nothing came in time.
    /// A closed connection is an `UnexpectedEof` error.
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize>;
    fn describe(&self) -> String;
}

fn eof() -> io::Error {
    io::Error::new(io::ErrorKind::UnexpectedEof, "connection closed")
}

/// Whether an IO error is the "nothing arrived in time" of a timed read.
fn is_timeout(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut | io::ErrorKind::Interrupted
    )
}

/// TCP, as network controllers (FluidNC, grblHAL) expose their serial protocol. Nagle is off:
/// character counting lives on small writes answered at once.
#[derive(Debug)]
pub struct TcpTransport {
    stream: TcpStream,
    peer: String,
    timeout: Option<Duration>,
    /// Poll a non-blocking socket instead of a receive timeout: Linux rounds `SO_RCVTIMEO`
    /// up to a scheduler tick (4–10 ms), far too coarse for a simulated serial line that must
    /// answer within a character time.
    polled: bool,
}

impl TcpTransport {
    pub fn connect(host: &str, port: u16) -> Result<TcpTransport, LinkError> {
        let url = format!("tcp://{host}:{port}");
        let fail = |reason: String| LinkError::Connect {
            url: url.clone(),
            reason,
            help: Some(
                "is the controller (or `lase sim --listen HOST:PORT`) running and listening there?"
                    .into(),
            ),
        };
        let addrs: Vec<_> = (host, port)
            .to_socket_addrs()
            .map_err(|e| fail(e.to_string()))?
            .collect();
        let mut last = String::from("no address");
        for a in addrs {
            match TcpStream::connect_timeout(&a, Duration::from_secs(5)) {
                Ok(s) => return TcpTransport::from_stream(s).map_err(|e| fail(e.to_string())),
                Err(e) => last = e.to_string(),
            }
        }
        Err(fail(last))
    }

    pub fn from_stream(stream: TcpStream) -> io::Result<TcpTransport> {
        stream.set_nodelay(true)?;
        let peer = stream
            .peer_addr()
            .map(|a| format!("tcp://{a}"))
            .unwrap_or_else(|_| "tcp".into());
        Ok(TcpTransport {
            stream,
            peer,
            timeout: None,
            polled: false,
        })
    }

    /// A transport whose timed reads wake within ~0.1 ms (see `polled`).
    pub fn polled(stream: TcpStream) -> io::Result<TcpTransport> {
        stream.set_nonblocking(true)?;
        let mut t = TcpTransport::from_stream(stream)?;
        t.polled = true;
        Ok(t)
    }
}

impl Transport for TcpTransport {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        if self.polled {
            // Non-blocking: finish the write, waiting for room as a blocking write would.
            let mut rest = bytes;
            while !rest.is_empty() {
                match self.stream.write(rest) {
                    Ok(0) => return Err(io::Error::new(io::ErrorKind::WriteZero, "closed")),
                    Ok(n) => rest = &rest[n..],
                    Err(e) if is_timeout(&e) => std::thread::sleep(Duration::from_micros(100)),
                    Err(e) => return Err(e),
                }
            }
            return Ok(());
        }
        self.stream.write_all(bytes)
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        if self.polled {
            let start = std::time::Instant::now();
            loop {
                match self.stream.read(buf) {
                    Ok(0) => return Err(eof()),
                    Ok(n) => return Ok(n),
                    Err(e) if is_timeout(&e) => {
                        let left = timeout.saturating_sub(start.elapsed());
                        if left.is_zero() {
                            return Ok(0);
                        }
                        std::thread::sleep(left.min(Duration::from_micros(100)));
                    }
                    Err(e) => return Err(e),
                }
            }
        }
        // A zero timeout means "block forever" to std; the shortest real wait stands in.
        let t = timeout.max(Duration::from_micros(50));
        if self.timeout != Some(t) {
            self.stream.set_read_timeout(Some(t))?;
            self.timeout = Some(t);
        }
        match self.stream.read(buf) {
            Ok(0) => Err(eof()),
            Ok(n) => Ok(n),
            Err(e) if is_timeout(&e) => Ok(0),
            Err(e) => Err(e),
        }
    }

    fn describe(&self) -> String {
        self.peer.clone()
    }
}

/// A serial port (USB-serial GRBL boards), 8N1 without flow control.
pub struct SerialTransport {
    port: Box<dyn serialport::SerialPort>,
    path: String,
    timeout: Option<Duration>,
}

impl std::fmt::Debug for SerialTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SerialTransport")
            .field("path", &self.path)
            .finish()
    }
}

impl SerialTransport {
    pub fn open(path: &str, baud: u32) -> Result<SerialTransport, LinkError> {
        let port = serialport::new(path, baud)
            .timeout(Duration::from_millis(10))
            .open()
            .map_err(|e| LinkError::Connect {
                url: format!("serial://{path}?baud={baud}"),
                reason: e.to_string(),
                help: Some(
                    "check the device path, that no other program holds the port, and that you may open it (the `dialout` group)"
                        .into(),
                ),
            })?;
        Ok(SerialTransport {
            port,
            path: format!("serial://{path}?baud={baud}"),
            timeout: None,
        })
    }
}

impl Transport for SerialTransport {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.port.write_all(bytes)?;
        self.port.flush()
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        let t = timeout.max(Duration::from_millis(1));
        if self.timeout != Some(t) {
            self.port.set_timeout(t).map_err(io::Error::other)?;
            self.timeout = Some(t);
        }
        match self.port.read(buf) {
            Ok(0) => Ok(0),
            Ok(n) => Ok(n),
            Err(e) if is_timeout(&e) => Ok(0),
            Err(e) => Err(e),
        }
    }

    fn describe(&self) -> String {
        self.path.clone()
    }
}

/// One end of an in-memory full-duplex pipe. Dropping an end closes the other's reads.
#[derive(Debug)]
pub struct PipeEnd {
    tx: Sender<Vec<u8>>,
    rx: Receiver<Vec<u8>>,
    pending: Vec<u8>,
    name: String,
}

/// Two connected pipe ends.
pub fn pipe(name: &str) -> (PipeEnd, PipeEnd) {
    let (a_tx, b_rx) = channel();
    let (b_tx, a_rx) = channel();
    (
        PipeEnd {
            tx: a_tx,
            rx: a_rx,
            pending: Vec::new(),
            name: name.to_string(),
        },
        PipeEnd {
            tx: b_tx,
            rx: b_rx,
            pending: Vec::new(),
            name: name.to_string(),
        },
    )
}

impl Transport for PipeEnd {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.tx
            .send(bytes.to_vec())
            .map_err(|_| io::Error::new(io::ErrorKind::BrokenPipe, "pipe closed"))
    }

    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        if self.pending.is_empty() {
            let first = match self.rx.recv_timeout(timeout) {
                Ok(b) => b,
                Err(RecvTimeoutError::Timeout) => return Ok(0),
                Err(RecvTimeoutError::Disconnected) => return Err(eof()),
            };
            self.pending = first;
            // Gather what else is already there, as a socket read would.
            while let Ok(more) = self.rx.try_recv() {
                self.pending.extend_from_slice(&more);
            }
        }
        let n = buf.len().min(self.pending.len());
        buf[..n].copy_from_slice(&self.pending[..n]);
        self.pending.drain(..n);
        Ok(n)
    }

    fn describe(&self) -> String {
        self.name.clone()
    }
}

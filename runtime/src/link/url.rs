//! Link URLs: `sim[://?options]`, `tcp://host:port`, `serial:///dev/ttyUSB0?baud=115200`,
//! `linuxcnc://host:port[?dir=LOCAL&remote-dir=ON-CONTROLLER&timeout=SECONDS]`.

use super::LinkError;
use super::sim::{Faults, SimOptions, TimeScale};
use std::fmt;

/// Where a job goes.
#[derive(Debug, Clone, PartialEq)]
pub enum LinkUrl {
    /// The simulated controller in this process.
    Sim(SimUrlOptions),
    Tcp {
        host: String,
        port: u16,
    },
    Serial {
        path: String,
        baud: u32,
    },
    /// LinuxCNC over linuxcncrsh: the program is a file the controller opens, written in
    /// `dir` and opened as `remote_dir` (see `linuxcnc::job::Placement`). `timeout` (s,
    /// default `linuxcnc::LIVE_TIMEOUT`) bounds every wait on linuxcncrsh: a reply, and a
    /// running program whose status stands still before lase checks that LinuxCNC's task
    /// still takes commands (`linuxcnc::job::follow`).
    LinuxCnc {
        host: String,
        port: u16,
        dir: Option<String>,
        remote_dir: Option<String>,
        timeout: Option<f64>,
    },
}

/// Options of the in-process simulator, from the URL's query (`sim://?time-scale=real`).
/// `None` leaves the choice to the command (`lase run` runs in real time) or to the simulated
/// firmware (its own RX buffer: GRBL 128 bytes, grblHAL 1024).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SimUrlOptions {
    pub time_scale: Option<TimeScale>,
    pub rx_buffer: Option<usize>,
    pub baud: Option<u32>,
    pub error_at_line: Vec<(u64, u32)>,
    /// The table's positioning error (`position-error=backlash=3um,random=5um`).
    pub position_error: Option<super::sim::poserr::PositionErrorConfig>,
}

impl SimUrlOptions {
    /// The simulator's options; a clock the URL leaves open runs as fast as it can (the REPL,
    /// `lase frame`; `lase run` chooses real time before it gets here).
    pub fn to_options(&self) -> SimOptions {
        SimOptions {
            time_scale: self.time_scale.unwrap_or(TimeScale::Max),
            rx_buffer: self.rx_buffer,
            baud: self.baud,
            faults: Faults {
                error_at_line: self.error_at_line.clone(),
                ..Faults::default()
            },
            keep: Some(super::sim::KEEP_LIVE),
            position_error: self.position_error,
            ..SimOptions::default()
        }
    }
}

impl LinkUrl {
    pub fn parse(url: &str) -> Result<LinkUrl, LinkError> {
        let bad = |reason: &str| LinkError::BadUrl {
            url: url.to_string(),
            reason: reason.to_string(),
        };
        let (scheme, rest) = match url.split_once("://") {
            Some((s, r)) => (s, r),
            None if url == "sim" => ("sim", ""),
            None => return Err(bad("expected SCHEME://…")),
        };
        let (body, query) = match rest.split_once('?') {
            Some((b, q)) => (b, q),
            None => (rest, ""),
        };
        let params: Vec<(&str, &str)> = query
            .split('&')
            .filter(|p| !p.is_empty())
            .map(|p| p.split_once('=').unwrap_or((p, "")))
            .collect();
        match scheme {
            "sim" => {
                if !body.is_empty() {
                    return Err(bad("`sim` takes options only: sim://?time-scale=real"));
                }
                let mut o = SimUrlOptions::default();
                for (k, v) in params {
                    match k {
                        "time-scale" => {
                            o.time_scale = Some(v.parse().map_err(|e: String| bad(&e))?)
                        }
                        "rx-buffer" => {
                            o.rx_buffer = Some(
                                v.parse()
                                    .ok()
                                    .filter(|n| *n >= 16)
                                    .ok_or_else(|| bad("rx-buffer is a byte count, at least 16"))?,
                            )
                        }
                        "baud" => {
                            o.baud = Some(
                                v.parse()
                                    .ok()
                                    .filter(|b| *b > 0)
                                    .ok_or_else(|| bad("baud is a positive number"))?,
                            )
                        }
                        "error-at-line" => o
                            .error_at_line
                            .push(super::sim::parse_error_at(v).map_err(|e| bad(&e))?),
                        "position-error" => {
                            o.position_error = Some(v.parse().map_err(|e: String| bad(&e))?)
                        }
                        other => return Err(bad(&format!("unknown sim option `{other}`"))),
                    }
                }
                Ok(LinkUrl::Sim(o))
            }
            "linuxcnc" => {
                let (host, port) = match body.trim_end_matches('/').rsplit_once(':') {
                    Some((h, p)) => (
                        h,
                        p.parse::<u16>()
                            .ok()
                            .filter(|p| *p > 0)
                            .ok_or_else(|| bad("the port is a number 1-65535"))?,
                    ),
                    None => (body.trim_end_matches('/'), super::linuxcnc::DEFAULT_PORT),
                };
                if host.is_empty() {
                    return Err(bad("expected linuxcnc://HOST:PORT"));
                }
                let (mut dir, mut remote_dir, mut timeout) = (None, None, None);
                for (k, v) in params {
                    match k {
                        "dir" if !v.is_empty() => dir = Some(v.to_string()),
                        "remote-dir" if !v.is_empty() => remote_dir = Some(v.to_string()),
                        "timeout" => {
                            timeout = Some(
                                v.parse::<f64>()
                                    .ok()
                                    .filter(|t| t.is_finite() && *t > 0.0 && *t <= 3600.0)
                                    .ok_or_else(|| {
                                        bad("timeout is a number of seconds, more than 0 and at most 3600")
                                    })?,
                            )
                        }
                        other => {
                            return Err(bad(&format!(
                                "unknown linuxcnc option `{other}` (dir=LOCAL, remote-dir=ON-CONTROLLER, timeout=SECONDS)"
                            )));
                        }
                    }
                }
                Ok(LinkUrl::LinuxCnc {
                    host: host
                        .trim_start_matches('[')
                        .trim_end_matches(']')
                        .to_string(),
                    port,
                    dir,
                    remote_dir,
                    timeout,
                })
            }
            "tcp" => {
                let (host, port) = body
                    .rsplit_once(':')
                    .ok_or_else(|| bad("expected tcp://HOST:PORT"))?;
                let port: u16 = port
                    .trim_end_matches('/')
                    .parse()
                    .map_err(|_| bad("the port is a number 1-65535"))?;
                if host.is_empty() || port == 0 {
                    return Err(bad("expected tcp://HOST:PORT"));
                }
                let host = host.trim_start_matches('[').trim_end_matches(']');
                Ok(LinkUrl::Tcp {
                    host: host.to_string(),
                    port,
                })
            }
            "serial" => {
                if body.is_empty() {
                    return Err(bad("expected serial:///dev/ttyUSB0?baud=115200"));
                }
                let mut baud = 115_200;
                for (k, v) in params {
                    match k {
                        "baud" => {
                            baud = v
                                .parse()
                                .ok()
                                .filter(|b| *b > 0)
                                .ok_or_else(|| bad("baud is a positive number"))?
                        }
                        other => return Err(bad(&format!("unknown serial option `{other}`"))),
                    }
                }
                Ok(LinkUrl::Serial {
                    path: body.to_string(),
                    baud,
                })
            }
            other => Err(LinkError::Unsupported {
                url: url.to_string(),
                help: Some(format!(
                    "`{other}` is not a link lase knows: use sim, tcp://HOST:PORT, serial://DEVICE?baud=N or linuxcnc://HOST:PORT"
                )),
            }),
        }
    }
}

impl fmt::Display for LinkUrl {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LinkUrl::Sim(o) => {
                write!(f, "sim")?;
                let mut q: Vec<String> = Vec::new();
                if let Some(t) = o.time_scale {
                    q.push(format!("time-scale={t}"));
                }
                if let Some(rx) = o.rx_buffer {
                    q.push(format!("rx-buffer={rx}"));
                }
                if let Some(b) = o.baud {
                    q.push(format!("baud={b}"));
                }
                for (line, code) in &o.error_at_line {
                    q.push(format!("error-at-line={line}:{code}"));
                }
                if let Some(p) = &o.position_error {
                    q.push(format!("position-error={p}"));
                }
                if !q.is_empty() {
                    write!(f, "://?{}", q.join("&"))?;
                }
                Ok(())
            }
            LinkUrl::Tcp { host, port } if host.contains(':') => write!(f, "tcp://[{host}]:{port}"),
            LinkUrl::Tcp { host, port } => write!(f, "tcp://{host}:{port}"),
            LinkUrl::Serial { path, baud } => write!(f, "serial://{path}?baud={baud}"),
            LinkUrl::LinuxCnc {
                host,
                port,
                dir,
                remote_dir,
                timeout,
            } => {
                let host = if host.contains(':') {
                    format!("[{host}]")
                } else {
                    host.clone()
                };
                write!(f, "linuxcnc://{host}:{port}")?;
                let timeout = timeout.map(|t| t.to_string());
                let q: Vec<String> = [
                    ("dir", dir),
                    ("remote-dir", remote_dir),
                    ("timeout", &timeout),
                ]
                .into_iter()
                .filter_map(|(k, v)| v.as_ref().map(|v| format!("{k}={v}")))
                .collect();
                if !q.is_empty() {
                    write!(f, "?{}", q.join("&"))?;
                }
                Ok(())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls_parse_and_print_back() {
        for u in [
            "sim",
            "tcp://127.0.0.1:5000",
            "serial:///dev/ttyUSB0?baud=115200",
            "sim://?time-scale=real&baud=115200",
            "sim://?rx-buffer=256",
            "linuxcnc://127.0.0.1:5007",
            "linuxcnc://cnc:5008?dir=/mnt/cnc&remote-dir=/home/cnc/nc",
            "linuxcnc://cnc:5007?timeout=2.5",
        ] {
            let parsed = LinkUrl::parse(u).unwrap();
            assert_eq!(LinkUrl::parse(&parsed.to_string()).unwrap(), parsed, "{u}");
        }
        assert_eq!(
            LinkUrl::parse("serial:///dev/ttyACM0").unwrap(),
            LinkUrl::Serial {
                path: "/dev/ttyACM0".into(),
                baud: 115_200
            }
        );
        assert!(LinkUrl::parse("tcp://host").is_err());
        assert_eq!(
            LinkUrl::parse("linuxcnc://cnc").unwrap().to_string(),
            "linuxcnc://cnc:5007"
        );
        assert!(LinkUrl::parse("linuxcnc://cnc:5007?upload=1").is_err());
        assert!(LinkUrl::parse("linuxcnc://cnc:5007?timeout=0").is_err());
        assert!(LinkUrl::parse("linuxcnc://cnc:5007?timeout=soon").is_err());
        assert!(LinkUrl::parse("ftp://x").is_err());
        assert!(LinkUrl::parse("sim://?time-scale=fast").is_err());
    }
}

//! The autopilot link of `host-sim egomotion --mavlink`: MAVLink 2 to a file or to a UDP
//! listener, as a flow sensor would send it over its serial port.
//!
//! Per frame pair the link sends OPTICAL_FLOW_RAD (PX4 reads it) and OPTICAL_FLOW (ArduPilot
//! reads it), both from the same readout, after a HEARTBEAT whenever a new second of the frame
//! clock begins (the first pair included). Every frame takes the next sequence number.
//!
//! A UDP listener is a ground station or MAVProxy with `udpout`-style input: datagrams go to it
//! whether or not it listens. One that starts late, stops or never exists costs nothing: a
//! failed send is counted and the run goes on. A destination that cannot be one (a host that
//! does not resolve, no route to it) is an error before any frame is read.

use std::ffi::OsStr;
use std::io::Write;
use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};
use std::path::PathBuf;

use kestrel::ego::mavlink::{
    encode_heartbeat, encode_optical_flow, encode_optical_flow_rad, EncodeError, MavlinkHeader,
    MAX_FRAME_LEN,
};
use kestrel::ego::{OpticalFlow, OpticalFlowRad};

use crate::commands::CommandError;
use crate::io::{describe_io_error, AtomicFile, OutputError};

/// The vehicle's MAVLink system id.
const SYSTEM_ID: u8 = 1;
/// Microseconds between heartbeats on the frame clock.
const HEARTBEAT_PERIOD_US: u64 = 1_000_000;

/// Where `--mavlink` sends the stream.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum MavlinkDestination {
    /// Raw bytes, back to back, written atomically at the end of the run.
    File(PathBuf),
    /// Datagrams to `host:port`, one MAVLink frame each.
    Udp {
        /// The host as given: a name, an IPv4 address or a bracketed IPv6 address.
        host: String,
        /// The port, 1 to 65535.
        port: u16,
    },
}

impl MavlinkDestination {
    /// `udp:HOST:PORT`, or any other text as a file path. The error says what is wrong with a
    /// `udp:` destination.
    ///
    /// ```
    /// use host_sim::egomotion::MavlinkDestination;
    /// let udp = MavlinkDestination::parse("udp:127.0.0.1:14550".as_ref()).unwrap();
    /// assert_eq!(udp, MavlinkDestination::Udp { host: "127.0.0.1".into(), port: 14550 });
    /// let v6 = MavlinkDestination::parse("udp:[::1]:14550".as_ref()).unwrap();
    /// assert_eq!(v6, MavlinkDestination::Udp { host: "::1".into(), port: 14550 });
    /// assert!(MavlinkDestination::parse("udp:".as_ref()).is_err());
    /// assert!(MavlinkDestination::parse("udp:localhost:0".as_ref()).is_err());
    /// let file = MavlinkDestination::parse("flow.bin".as_ref()).unwrap();
    /// assert_eq!(file, MavlinkDestination::File("flow.bin".into()));
    /// ```
    pub fn parse(text: &OsStr) -> Result<Self, String> {
        let Some(address) = text.to_str().and_then(|t| t.strip_prefix("udp:")) else {
            return Ok(Self::File(PathBuf::from(text)));
        };
        let Some((host, port)) = address.rsplit_once(':') else {
            return Err(format!(
                "a UDP destination is udp:HOST:PORT, e.g. udp:127.0.0.1:14550 (got \"udp:{address}\")"
            ));
        };
        let host = host
            .strip_prefix('[')
            .and_then(|h| h.strip_suffix(']'))
            .unwrap_or(host);
        if host.is_empty() {
            return Err(format!(
                "udp:HOST:PORT needs a host (got \"udp:{address}\")"
            ));
        }
        match port.parse::<u16>() {
            Ok(port) if port > 0 => Ok(Self::Udp {
                host: host.to_owned(),
                port,
            }),
            _ => Err(format!(
                "the port must be a number from 1 to 65535 (got \"{port}\")"
            )),
        }
    }

    /// The destination as the user wrote it.
    fn name(&self) -> String {
        match self {
            Self::File(path) => path.display().to_string(),
            Self::Udp { host, port } if host.contains(':') => format!("udp:[{host}]:{port}"),
            Self::Udp { host, port } => format!("udp:{host}:{port}"),
        }
    }
}

/// What a UDP link could not deliver.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct SendFailures {
    /// Datagrams the system refused to send (or that a missing listener bounced).
    pub failed: u64,
    /// Datagrams sent or attempted.
    pub attempted: u64,
    /// The last failure, described.
    pub last: Option<String>,
}

/// Where the frames go.
enum Sink {
    File(AtomicFile),
    Udp {
        socket: UdpSocket,
        failures: SendFailures,
    },
}

/// An open MAVLink stream with its sequence counter and heartbeat clock.
pub struct MavlinkLink {
    name: String,
    sink: Sink,
    header: MavlinkHeader,
    next_heartbeat_us: u64,
}

impl MavlinkLink {
    /// Opens `destination`: creates the file, or resolves the host and points a socket at it.
    pub fn open(destination: &MavlinkDestination) -> Result<Self, CommandError> {
        let name = destination.name();
        let sink = match destination {
            MavlinkDestination::File(path) => Sink::File(AtomicFile::create(path)?),
            MavlinkDestination::Udp { host, port } => Sink::Udp {
                socket: udp_socket(host, *port).map_err(|p| OutputError {
                    output: name.clone(),
                    problem: p,
                })?,
                failures: SendFailures::default(),
            },
        };
        Ok(Self {
            name,
            sink,
            header: MavlinkHeader::flow_sensor(SYSTEM_ID),
            next_heartbeat_us: 0,
        })
    }

    /// Sends one frame pair's readout taken at `time_us` on the frame clock: a HEARTBEAT when
    /// a new second has begun, then OPTICAL_FLOW_RAD and OPTICAL_FLOW.
    pub fn send(
        &mut self,
        time_us: u64,
        rad: &OpticalFlowRad,
        flow: &OpticalFlow,
    ) -> Result<(), CommandError> {
        if time_us >= self.next_heartbeat_us {
            self.next_heartbeat_us = (time_us / HEARTBEAT_PERIOD_US + 1) * HEARTBEAT_PERIOD_US;
            self.frame(encode_heartbeat)?;
        }
        self.frame(|header, buf| encode_optical_flow_rad(rad, header, buf))?;
        self.frame(|header, buf| encode_optical_flow(flow, header, buf))
    }

    /// Encodes one frame with the next sequence number and sends it.
    fn frame(
        &mut self,
        encode: impl FnOnce(MavlinkHeader, &mut [u8]) -> Result<usize, EncodeError>,
    ) -> Result<(), CommandError> {
        let mut buf = [0u8; MAX_FRAME_LEN];
        let len = encode(self.header.advance(), &mut buf)
            .map_err(|e| CommandError::Processing(format!("MAVLink: {e}")))?;
        let frame = buf.get(..len).unwrap_or(&[]);
        match &mut self.sink {
            Sink::File(file) => file
                .write_all(frame)
                .map_err(|e| CommandError::Output(file.write_error(&e))),
            Sink::Udp { socket, failures } => {
                failures.attempted += 1;
                if let Err(e) = socket.send(frame) {
                    failures.failed += 1;
                    failures.last = Some(describe_io_error(&e));
                }
                Ok(())
            }
        }
    }

    /// Ends the stream: commits the file, or returns what the UDP link could not send.
    pub fn finish(self) -> Result<Option<(String, SendFailures)>, CommandError> {
        match self.sink {
            Sink::File(file) => {
                file.commit()?;
                Ok(None)
            }
            Sink::Udp { failures, .. } if failures.failed > 0 => Ok(Some((self.name, failures))),
            Sink::Udp { .. } => Ok(None),
        }
    }
}

/// A UDP socket connected to `host:port`: the first address the host resolves to that a
/// socket can be pointed at. Connecting checks the route, and makes a missing listener's
/// "port unreachable" show up as a failed send instead of vanishing.
fn udp_socket(host: &str, port: u16) -> Result<UdpSocket, String> {
    let addresses: Vec<SocketAddr> = (host, port)
        .to_socket_addrs()
        .map_err(|e| format!("cannot resolve the host \"{host}\" ({})", plain(&e)))?
        .collect();
    let mut last = format!("the host \"{host}\" has no address");
    for address in addresses {
        let local: SocketAddr = if address.is_ipv4() {
            ([0, 0, 0, 0], 0).into()
        } else {
            ([0u16; 8], 0).into()
        };
        let attempt = UdpSocket::bind(local).and_then(|socket| {
            socket.connect(address)?;
            Ok(socket)
        });
        match attempt {
            Ok(socket) => return Ok(socket),
            Err(e) => last = format!("cannot send to {address}: {}", describe_io_error(&e)),
        }
    }
    Err(last)
}

/// An I/O error's text without the `(os error N)` suffix.
fn plain(error: &std::io::Error) -> String {
    let text = error.to_string();
    match text.find(" (os error") {
        Some(at) => text[..at].to_owned(),
        None => text,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn malformed_udp_destinations_say_why() {
        let problem = |t: &str| MavlinkDestination::parse(t.as_ref()).unwrap_err();
        assert!(problem("udp:").contains("udp:HOST:PORT"));
        assert!(problem("udp::14550").contains("needs a host"));
        assert!(problem("udp:localhost:").contains("port must be"));
        assert!(problem("udp:localhost:99999").contains("(got \"99999\")"));
        assert!(problem("udp:localhost:port").contains("(got \"port\")"));
    }

    #[test]
    fn an_unresolvable_host_fails_when_the_link_opens() {
        let destination = MavlinkDestination::Udp {
            host: "no-such-host.invalid".into(),
            port: 14550,
        };
        let error = MavlinkLink::open(&destination).err().unwrap().to_string();
        assert!(
            error.starts_with("udp:no-such-host.invalid:14550: cannot resolve"),
            "{error}"
        );
    }

    #[test]
    fn a_missing_listener_is_counted_not_fatal() {
        // A port nothing listens on: bind one, note it, close it.
        let port = UdpSocket::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let destination = MavlinkDestination::Udp {
            host: "127.0.0.1".into(),
            port,
        };
        let mut link = MavlinkLink::open(&destination).unwrap();
        let rad = OpticalFlowRad::default();
        for k in 0..5 {
            link.send(k * 10_000, &rad, &OpticalFlow::default())
                .unwrap();
        }
        // 1 heartbeat and 5 pairs; the refusals (ICMP port unreachable) may be counted.
        if let Some((_, failures)) = link.finish().unwrap() {
            assert_eq!(failures.attempted, 11);
        }
    }
}

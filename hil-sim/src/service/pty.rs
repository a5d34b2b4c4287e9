//! A real pseudo-terminal for the service port (service.md 9): the simulation holds the
//! master, a client (`plcctl --port <path>`, a test) opens the slave path as a serial
//! port. Raw mode is set once, here, so that a client that opens the path as a plain
//! file gets the bytes unchanged.

use std::fs::File;
use std::io::{ErrorKind, Read, Write};
use std::os::fd::{AsFd, OwnedFd};
use std::path::PathBuf;

use anyhow::{Context, Result};
use nix::fcntl::{fcntl, FcntlArg, OFlag};
use nix::poll::{poll, PollFd, PollFlags, PollTimeout};
use nix::pty::openpty;
use nix::sys::termios::{cfmakeraw, tcgetattr, tcsetattr, SetArg};

/// The master side of a pty pair.
pub struct Pty {
    master: File,
    path: PathBuf,
}

impl Pty {
    /// Opens a pty pair in raw mode and closes the slave (the client opens it by path).
    pub fn open() -> Result<Pty> {
        let pair = openpty(None, None).context("cannot open a pseudo-terminal")?;
        let path = nix::unistd::ttyname(&pair.slave).context("pty slave name")?;
        let mut t = tcgetattr(&pair.slave).context("pty attributes")?;
        cfmakeraw(&mut t);
        tcsetattr(&pair.slave, SetArg::TCSANOW, &t).context("pty raw mode")?;
        let master: OwnedFd = pair.master;
        let flags = fcntl(&master, FcntlArg::F_GETFL).context("pty flags")?;
        fcntl(
            &master,
            FcntlArg::F_SETFL(OFlag::from_bits_truncate(flags) | OFlag::O_NONBLOCK),
        )
        .context("pty non-blocking")?;
        drop(pair.slave);
        Ok(Pty {
            master: File::from(master),
            path,
        })
    }

    /// The slave's path (`/dev/pts/N`), printed as `service: <path>`.
    pub fn path(&self) -> &std::path::Path {
        &self.path
    }

    /// Whether a client has the slave open: the master reports a hang-up while nobody
    /// does.
    pub fn client(&self) -> bool {
        let mut fds = [PollFd::new(self.master.as_fd(), PollFlags::POLLIN)];
        match poll(&mut fds, PollTimeout::ZERO) {
            Ok(_) => !fds[0]
                .revents()
                .is_some_and(|r| r.contains(PollFlags::POLLHUP)),
            Err(_) => false,
        }
    }

    /// Everything the client has written so far (nothing without a client).
    pub fn read_available(&mut self) -> Vec<u8> {
        let mut all = Vec::new();
        let mut buf = [0u8; 256];
        loop {
            match self.master.read(&mut buf) {
                Ok(0) => return all,
                Ok(n) => all.extend_from_slice(buf.get(..n).unwrap_or(&[])),
                // WouldBlock: nothing more; EIO: no client.
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(_) => return all,
            }
        }
    }

    /// Bytes to the client; dropped without one (a serial line without a listener).
    pub fn write(&mut self, bytes: &[u8]) {
        if bytes.is_empty() || !self.client() {
            return;
        }
        let mut rest = bytes;
        while !rest.is_empty() {
            match self.master.write(rest) {
                Ok(0) => return,
                Ok(n) => rest = rest.get(n..).unwrap_or(&[]),
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(e) if e.kind() == ErrorKind::WouldBlock => {
                    // The client does not read: wait for room, as a UART would stall.
                    let mut fds = [PollFd::new(self.master.as_fd(), PollFlags::POLLOUT)];
                    if poll(&mut fds, PollTimeout::from(100u8)).unwrap_or(0) == 0 {
                        return;
                    }
                }
                Err(_) => return,
            }
        }
    }
}

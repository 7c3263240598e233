//! A live view of a render: after every pass, the image so far is streamed to the tev viewer
//! over its network protocol (`--display HOST:PORT`), and every so many seconds a PNG preview
//! is rewritten for machines without a screen (`--preview SECONDS`). Both only read the image
//! between passes, so the render's outputs are the same bytes with or without them; a viewer
//! that cannot be reached costs a warning, never the render.
//! Book: "Measuring a renderer" (watching a render).
//!
//! tev's protocol is a TCP stream of packets: a little-endian `u32` length that counts the
//! whole packet (its own four bytes included), a `u8` type, then the payload; strings end in a
//! NUL byte, integers and floats are little-endian. Two packets are sent: `CreateImage` (type
//! 4) when the connection opens, and `UpdateImageV3` (type 6, the update with per-channel
//! offsets and strides, which tev has read since 1.18 and pbrt-v4 sends) with the pixels.

use std::io::Write;
use std::net::{Shutdown, SocketAddr, TcpStream, ToSocketAddrs};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use crate::image_io::{self, Image};

/// The port tev listens on unless told otherwise.
pub const TEV_PORT: u16 = 14158;

/// tev's `CreateImage` packet type: a new image of a size and channels, filled with zeros.
pub const CREATE_IMAGE: u8 = 4;

/// tev's `UpdateImageV3` packet type: a rectangle of pixels, each channel at an offset and a
/// stride into the packet's floats.
pub const UPDATE_IMAGE_V3: u8 = 6;

/// The channels sent, in the order of [`crate::spectrum::Rgb`].
pub const CHANNELS: [&str; 3] = ["R", "G", "B"];

/// The most floats one update carries: larger images go as strips of rows (4 MiB each), so
/// that neither side holds a whole large image twice.
const MAX_FLOATS: usize = 1 << 20;

/// How long a connection attempt may hold up the render.
const CONNECT_TIMEOUT: Duration = Duration::from_millis(500);

/// How long one write may block before the viewer is given up (a stalled tev).
const WRITE_TIMEOUT: Duration = Duration::from_secs(2);

/// The first wait before trying an unreachable viewer again; each failure doubles it, up to
/// [`MAX_RETRY`], so a render without a viewer spends at most a connection attempt a minute.
const FIRST_RETRY: Duration = Duration::from_secs(5);
const MAX_RETRY: Duration = Duration::from_secs(60);

/// `--display HOST:PORT`, checked and resolved when the command line is read.
#[derive(Clone, Debug, PartialEq)]
pub struct TevAddress {
    /// As given (for messages).
    pub text: String,
    /// What it resolves to, tried in order.
    pub addrs: Vec<SocketAddr>,
}

/// Reads `HOST:PORT` (`127.0.0.1:14158`, `localhost:14158`, `[::1]:14158`), resolving the
/// host now, so that a typo is refused before any work.
pub fn parse_address(text: &str) -> Result<TevAddress, String> {
    let usage = format!("expected HOST:PORT, e.g. 127.0.0.1:{TEV_PORT} (tev's default)");
    let Some((host, port)) = text.rsplit_once(':') else {
        return Err(format!("`{text}` has no port: {usage}"));
    };
    if host.is_empty() {
        return Err(format!("`{text}` has no host: {usage}"));
    }
    match port.parse::<u16>() {
        Ok(p) if p > 0 => {}
        _ => return Err(format!("`{port}` is no port (1 to 65535): {usage}")),
    }
    let addrs: Vec<SocketAddr> = text
        .to_socket_addrs()
        .map_err(|e| format!("cannot resolve `{text}`: {e}"))?
        .collect();
    if addrs.is_empty() {
        return Err(format!("`{text}` resolves to no address"));
    }
    Ok(TevAddress {
        text: text.to_string(),
        addrs,
    })
}

/// A packet being written: its length field is filled in by [`Packet::bytes`].
struct Packet(Vec<u8>);

impl Packet {
    fn new(kind: u8) -> Self {
        Packet(vec![0, 0, 0, 0, kind])
    }

    fn flag(mut self, b: bool) -> Self {
        self.0.push(u8::from(b));
        self
    }

    /// A string as tev reads it: its bytes up to a NUL (a NUL inside would end it early).
    fn text(mut self, s: &str) -> Self {
        self.0.extend(s.bytes().filter(|&b| b != 0));
        self.0.push(0);
        self
    }

    fn i32(mut self, v: i32) -> Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }

    fn i64(mut self, v: i64) -> Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }

    fn f32(mut self, v: f32) -> Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// The packet with its length, which counts the length field itself.
    fn bytes(mut self) -> Vec<u8> {
        let n = self.0.len() as u32;
        self.0[..4].copy_from_slice(&n.to_le_bytes());
        self.0
    }
}

/// tev's `CreateImage`: an image `name` of `width` x `height` pixels with channels R, G, B;
/// `grab_focus` brings it to the front.
pub fn create_image(name: &str, grab_focus: bool, width: u32, height: u32) -> Vec<u8> {
    let mut p = Packet::new(CREATE_IMAGE)
        .flag(grab_focus)
        .text(name)
        .i32(width as i32)
        .i32(height as i32)
        .i32(CHANNELS.len() as i32);
    for c in CHANNELS {
        p = p.text(c);
    }
    p.bytes()
}

/// tev's `UpdateImageV3` of rows `y0..y1` of `image`: the pixels as they lie in memory
/// (R, G, B interleaved), so channel c starts at float c with a stride of 3.
pub fn update_image(name: &str, image: &Image, y0: u32, y1: u32) -> Vec<u8> {
    let n = CHANNELS.len() as i64;
    let mut p = Packet::new(UPDATE_IMAGE_V3)
        .flag(false)
        .text(name)
        .i32(n as i32);
    for c in CHANNELS {
        p = p.text(c);
    }
    p = p
        .i32(0)
        .i32(y0 as i32)
        .i32(image.width as i32)
        .i32((y1 - y0) as i32);
    for c in 0..n {
        p = p.i64(c);
    }
    for _ in 0..n {
        p = p.i64(n);
    }
    let w = image.width as usize;
    for px in &image.pixels[y0 as usize * w..y1 as usize * w] {
        for v in px.to_array() {
            p = p.f32(v);
        }
    }
    p.bytes()
}

/// The row ranges of the updates of an image of `width` x `height`: strips of at most
/// [`MAX_FLOATS`] floats (at least one row).
pub fn strips(width: u32, height: u32) -> Vec<(u32, u32)> {
    let per_row = (width as usize * CHANNELS.len()).max(1);
    let rows = (MAX_FLOATS / per_row).max(1) as u32;
    (0..height)
        .step_by(rows as usize)
        .map(|y| (y, (y + rows).min(height)))
        .collect()
}

/// A connection to tev, made before the render (or when the first image is shown) and made again, after a growing
/// wait, when it fails: a missing viewer is one warning, not an error.
pub struct Tev {
    address: TevAddress,
    name: String,
    stream: Option<TcpStream>,
    next_try: Instant,
    wait: Duration,
    warned: bool,
}

impl Tev {
    /// A client that shows its images in tev as `name`.
    pub fn new(address: TevAddress, name: &str) -> Self {
        Tev {
            address,
            name: name.to_string(),
            stream: None,
            next_try: Instant::now(),
            wait: FIRST_RETRY,
            warned: false,
        }
    }

    /// Connects before the first pass, so that the image (black until the first pass ends)
    /// and a missing viewer's warning come at once.
    pub fn start(&mut self, width: u32, height: u32) {
        if self.stream.is_none() {
            self.connect(width, height);
        }
    }

    /// Whether [`Tev::show`] would send anything now (connected, or due to try again).
    pub fn wants_image(&self) -> bool {
        self.stream.is_some() || Instant::now() >= self.next_try
    }

    /// Sends `image` (creating it in tev first on a new connection); a failure drops the
    /// connection, warns once, and leaves the render to go on.
    pub fn show(&mut self, image: &Image) {
        if self.stream.is_none() && !self.connect(image.width, image.height) {
            return;
        }
        let name = self.name.clone();
        let sent = self.stream.as_mut().map_or(Ok(()), |s| {
            strips(image.width, image.height)
                .into_iter()
                .try_for_each(|(y0, y1)| s.write_all(&update_image(&name, image, y0, y1)))
        });
        if let Err(e) = sent {
            self.fail(&format!("lost tev at {}: {e}", self.address.text));
        }
    }

    /// Connects when due and creates the image; whether a connection is open.
    fn connect(&mut self, width: u32, height: u32) -> bool {
        if Instant::now() < self.next_try {
            return false;
        }
        match self.open(width, height) {
            Ok(s) => {
                if self.warned {
                    eprintln!("tev at {}: connected", self.address.text);
                }
                self.stream = Some(s);
                self.warned = false;
                self.wait = FIRST_RETRY;
                true
            }
            Err(e) => {
                let m = format!("cannot reach tev at {}: {e}", self.address.text);
                self.fail(&m);
                false
            }
        }
    }

    /// A new connection, with the image created (and brought to the front).
    fn open(&self, width: u32, height: u32) -> std::io::Result<TcpStream> {
        let mut last = None;
        for a in &self.address.addrs {
            match TcpStream::connect_timeout(a, CONNECT_TIMEOUT) {
                Ok(mut s) => {
                    s.set_write_timeout(Some(WRITE_TIMEOUT))?;
                    s.set_nodelay(true)?;
                    s.write_all(&create_image(&self.name, true, width, height))?;
                    return Ok(s);
                }
                Err(e) => last = Some(e),
            }
        }
        Err(last.unwrap_or_else(|| std::io::Error::other("no address")))
    }

    /// Drops the connection, warns (once until the next connection) and waits before the
    /// next attempt.
    fn fail(&mut self, message: &str) {
        self.stream = None;
        if !self.warned {
            eprintln!(
                "warning: --display: {message}; the render goes on (and tries again now and then)"
            );
            self.warned = true;
        }
        self.next_try = Instant::now() + self.wait;
        self.wait = (self.wait * 2).min(MAX_RETRY);
    }
}

impl Drop for Tev {
    /// Ends the stream cleanly: tev reads every packet, then the end of the connection.
    fn drop(&mut self) {
        if let Some(s) = &self.stream {
            let _ = s.shutdown(Shutdown::Write);
        }
    }
}

/// `--preview SECONDS`: the PNG rewritten with the image so far when that many seconds have
/// passed since the last one (or since the render started).
pub struct Preview {
    path: PathBuf,
    every: Duration,
    last: Instant,
    warned: bool,
}

impl Preview {
    pub fn new(path: PathBuf, seconds: f64) -> Self {
        Preview {
            path,
            every: Duration::from_secs_f64(seconds.max(0.0)),
            last: Instant::now(),
            warned: false,
        }
    }

    /// Whether a preview is due.
    pub fn due(&self) -> bool {
        self.last.elapsed() >= self.every
    }

    /// Writes `image` (atomically: a reader never sees half a PNG); a failed write warns once,
    /// the final write reports it as an error.
    pub fn write(&mut self, image: &Image) {
        if let Err(e) = image_io::write_png(&self.path, image) {
            if !self.warned {
                eprintln!("warning: --preview: {e}");
                self.warned = true;
            }
        }
        self.last = Instant::now();
    }
}

/// The live views of one render: tev, the PNG preview, either or both.
pub struct Live {
    pub tev: Option<Tev>,
    pub preview: Option<Preview>,
}

impl Live {
    /// Whether any view is asked for (no view: the passes are not even asked for an image).
    pub fn active(&self) -> bool {
        self.tev.is_some() || self.preview.is_some()
    }

    /// After a pass: asks for the image (a copy of the film) only when a view wants it now.
    pub fn pass(&mut self, image: &dyn Fn() -> Option<Image>) {
        let to_tev = self.tev.as_ref().is_some_and(Tev::wants_image);
        let to_png = self.preview.as_ref().is_some_and(Preview::due);
        if !(to_tev || to_png) {
            return;
        }
        let Some(img) = image() else { return };
        if let (true, Some(t)) = (to_tev, self.tev.as_mut()) {
            t.show(&img);
        }
        if let (true, Some(p)) = (to_png, self.preview.as_mut()) {
            p.write(&img);
        }
    }
}

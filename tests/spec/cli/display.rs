//! The live view: `--display HOST:PORT` speaks tev's network protocol to whatever listens
//! there. A small server here reads the stream the way tev reads it (a little-endian `u32`
//! length counting the whole packet, a type byte, the payload: NUL-terminated strings,
//! little-endian numbers) and rebuilds the image from the updates, which must be the image the
//! render writes, bit for bit. Without a viewer the render goes on with a warning; neither
//! `--display` nor `--preview` changes a byte of the outputs.

use std::io::Read;
use std::net::{TcpListener, TcpStream};
use std::path::Path;
use std::process::Output;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use crate::common;
use common::cli::{pathspace, scratch, stderr};
use pathspace::cli::display::{self, Live, Preview};
use pathspace::image_io::{self, Image};

const GROUP: &str = "display";

/// A render of the embedded fog box, not square (so that width and height cannot be
/// swapped unseen), 8 spp: two passes of 4.
fn render(dir: &Path, name: &str, extra: &[&str]) -> (Output, Vec<u8>) {
    let exr = dir.join(format!("{name}.exr"));
    let mut args = vec![
        "render",
        "--resolution",
        "12x8",
        "--spp",
        "8",
        "--seed",
        "7",
        "--reproducible",
        "-o",
        exr.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let out = pathspace(&args);
    assert!(out.status.success(), "{}", stderr(&out));
    let bytes = std::fs::read(&exr).unwrap();
    (out, bytes)
}

/// A packet as tev decodes it.
#[derive(Debug)]
enum Packet {
    Create {
        grab_focus: bool,
        name: String,
        width: i32,
        height: i32,
        channels: Vec<String>,
    },
    Update {
        name: String,
        channels: Vec<String>,
        rect: [i32; 4],
        offsets: Vec<i64>,
        strides: Vec<i64>,
        floats: Vec<f32>,
    },
}

/// A reader over one packet's bytes that refuses to read past its end (tev throws there).
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> &[u8] {
        assert!(
            self.at + n <= self.bytes.len(),
            "read past the packet's end"
        );
        self.at += n;
        &self.bytes[self.at - n..self.at]
    }
    fn flag(&mut self) -> bool {
        let b = self.take(1)[0];
        assert!(b <= 1, "a bool is 0 or 1, not {b}");
        b == 1
    }
    fn i32(&mut self) -> i32 {
        i32::from_le_bytes(self.take(4).try_into().unwrap())
    }
    fn i64(&mut self) -> i64 {
        i64::from_le_bytes(self.take(8).try_into().unwrap())
    }
    fn text(&mut self) -> String {
        let end = self.bytes[self.at..]
            .iter()
            .position(|&b| b == 0)
            .expect("a string ends in NUL");
        let s = String::from_utf8(self.take(end).to_vec()).unwrap();
        self.take(1);
        s
    }
    fn texts(&mut self, n: i32) -> Vec<String> {
        (0..n).map(|_| self.text()).collect()
    }
}

/// Splits a stream into packets and decodes each (tev's types 4, CreateImage, and 6,
/// UpdateImageV3); every packet must be consumed exactly.
fn packets(stream: &[u8]) -> Vec<Packet> {
    let mut out = Vec::new();
    let mut rest = stream;
    while !rest.is_empty() {
        assert!(rest.len() >= 5, "a truncated packet header");
        let len = u32::from_le_bytes(rest[..4].try_into().unwrap()) as usize;
        assert!(
            (5..=rest.len()).contains(&len),
            "length field {len} with {} bytes left",
            rest.len()
        );
        let mut r = Reader {
            bytes: &rest[..len],
            at: 5,
        };
        out.push(match rest[4] {
            4 => {
                let (grab_focus, name) = (r.flag(), r.text());
                let (width, height, n) = (r.i32(), r.i32(), r.i32());
                let channels = r.texts(n);
                Packet::Create {
                    grab_focus,
                    name,
                    width,
                    height,
                    channels,
                }
            }
            6 => {
                let (_grab, name, n) = (r.flag(), r.text(), r.i32());
                let channels = r.texts(n);
                let rect = [r.i32(), r.i32(), r.i32(), r.i32()];
                let offsets: Vec<i64> = (0..n).map(|_| r.i64()).collect();
                let strides: Vec<i64> = (0..n).map(|_| r.i64()).collect();
                let floats = r.take(len - r.at);
                let floats = floats
                    .chunks_exact(4)
                    .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
                    .collect();
                Packet::Update {
                    name,
                    channels,
                    rect,
                    offsets,
                    strides,
                    floats,
                }
            }
            t => panic!("packet type {t} is not sent"),
        });
        assert_eq!(r.at, len, "bytes left in a packet");
        rest = &rest[len..];
    }
    out
}

/// Listens on a free port of 127.0.0.1 and collects what one client sends until it closes;
/// gives up on a client once `done` is set (the render has exited) and none came.
fn serve(done: Arc<AtomicBool>) -> (u16, std::thread::JoinHandle<Vec<u8>>) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    listener.set_nonblocking(true).unwrap();
    let handle = std::thread::spawn(move || loop {
        match listener.accept() {
            Ok((stream, _)) => return read_all(stream),
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                if done.load(Ordering::SeqCst) {
                    return Vec::new();
                }
                std::thread::sleep(Duration::from_millis(10));
            }
            Err(e) => panic!("accept: {e}"),
        }
    });
    (port, handle)
}

/// Everything a client sends until it closes (a stalled client is cut off after a minute).
fn read_all(mut stream: TcpStream) -> Vec<u8> {
    stream.set_nonblocking(false).unwrap();
    stream
        .set_read_timeout(Some(Duration::from_secs(60)))
        .unwrap();
    let mut bytes = Vec::new();
    stream.read_to_end(&mut bytes).unwrap();
    bytes
}

/// Applies an update to `canvas` (width `w`) as tev does: channel c of pixel i of the
/// rectangle is float `offset[c] + i * stride[c]`.
fn apply(
    canvas: &mut [[f32; 3]],
    w: usize,
    rect: [i32; 4],
    offsets: &[i64],
    strides: &[i64],
    floats: &[f32],
) {
    let [x, y, rw, rh] = rect.map(|v| v as usize);
    for i in 0..rw * rh {
        let (px, py) = (x + i % rw, y + i / rw);
        for c in 0..3 {
            let at = offsets[c] as usize + i * strides[c] as usize;
            canvas[py * w + px][c] = floats[at];
        }
    }
}

#[test]
fn tev_receives_the_image_of_every_pass_and_the_last_is_the_written_image() {
    let dir = scratch(GROUP, "stream");
    let done = Arc::new(AtomicBool::new(false));
    let (port, server) = serve(done.clone());
    let address = format!("127.0.0.1:{port}");
    let (out, shown) = render(&dir, "shown", &["--display", &address]);
    done.store(true, Ordering::SeqCst);
    let stream = server.join().unwrap();
    assert!(!stderr(&out).contains("warning"), "{}", stderr(&out));
    let packets = packets(&stream);
    let (w, h) = (12usize, 8usize);
    let name = match &packets[0] {
        Packet::Create {
            grab_focus,
            name,
            width,
            height,
            channels,
        } => {
            assert!(grab_focus);
            assert_eq!((*width, *height), (w as i32, h as i32));
            assert_eq!(channels, &["R", "G", "B"]);
            name.clone()
        }
        p => panic!("the first packet creates the image, not {p:?}"),
    };
    let mut canvas = vec![[f32::NAN; 3]; w * h];
    let mut frames = 0;
    for p in &packets[1..] {
        let Packet::Update {
            name: n,
            channels,
            rect,
            offsets,
            strides,
            floats,
        } = p
        else {
            panic!("only updates follow the creation, not {p:?}");
        };
        assert_eq!(
            (n, channels.as_slice()),
            (&name, &["R", "G", "B"].map(String::from)[..])
        );
        assert!(
            rect[0] >= 0
                && rect[1] >= 0
                && (rect[0] + rect[2]) as usize <= w
                && (rect[1] + rect[3]) as usize <= h
        );
        frames += usize::from(rect[0] == 0 && rect[1] == 0);
        apply(&mut canvas, w, *rect, offsets, strides, floats);
    }
    assert!(
        frames >= 2,
        "8 spp are 2 passes, each shown: {frames} updates"
    );
    let (written, _) = image_io::read_exr(&dir.join("shown.exr")).unwrap();
    let bits = |p: [f32; 3]| p.map(f32::to_bits);
    let expected: Vec<_> = written.pixels.iter().map(|p| bits(p.to_array())).collect();
    let got: Vec<_> = canvas.iter().map(|&p| bits(p)).collect();
    assert_eq!(got, expected, "the last update is the written image");
    // and the view changed nothing of the render
    let (_, plain) = render(&dir, "plain", &[]);
    assert!(shown == plain, "the EXR is the same bytes with --display");
}

#[test]
fn a_missing_viewer_is_a_warning_and_the_render_goes_on() {
    let dir = scratch(GROUP, "missing");
    // a port that was free a moment ago: nobody listens there now
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let address = format!("127.0.0.1:{port}");
    let (out, shown) = render(&dir, "shown", &["--display", &address]);
    let e = stderr(&out);
    assert_eq!(e.matches("warning: --display").count(), 1, "{e}");
    assert!(e.contains("cannot reach tev"), "{e}");
    let (_, plain) = render(&dir, "plain", &[]);
    assert!(shown == plain, "the EXR is the same bytes without a viewer");
}

#[test]
fn previews_leave_the_outputs_as_they_were() {
    let dir = scratch(GROUP, "preview");
    let (out, previewed) = render(&dir, "previewed", &["--preview", "0"]);
    assert!(!stderr(&out).contains("warning"), "{}", stderr(&out));
    let (_, plain) = render(&dir, "plain", &[]);
    assert!(
        previewed == plain,
        "the EXR is the same bytes with --preview"
    );
    let png = |n: &str| std::fs::read(dir.join(n)).unwrap();
    assert_eq!(png("previewed.png"), png("plain.png"));
    assert!(!dir.join(".previewed.png.partial").exists());
}

#[test]
fn a_due_preview_writes_the_image_as_png_and_an_early_one_waits() {
    let dir = scratch(GROUP, "due");
    let mut image = Image::new(5, 3);
    for (i, p) in image.pixels.iter_mut().enumerate() {
        *p = pathspace::spectrum::Rgb::new(i as f32 / 15.0, 0.5, 1.0 - i as f32 / 15.0);
    }
    let (due, early) = (dir.join("due.png"), dir.join("early.png"));
    let mut live = Live {
        tev: None,
        preview: Some(Preview::new(due.clone(), 0.0)),
    };
    let asked = std::cell::Cell::new(0);
    let get = || {
        asked.set(asked.get() + 1);
        Some(image.clone())
    };
    live.pass(&get);
    let reference = dir.join("reference.png");
    image_io::write_png(&reference, &image).unwrap();
    assert_eq!(
        std::fs::read(&due).unwrap(),
        std::fs::read(&reference).unwrap()
    );
    let decoded = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&due).unwrap()))
        .read_info()
        .unwrap();
    assert_eq!((decoded.info().width, decoded.info().height), (5, 3));
    let mut live = Live {
        tev: None,
        preview: Some(Preview::new(early.clone(), 3600.0)),
    };
    live.pass(&get);
    assert!(!early.exists(), "an hour has not passed");
    assert_eq!(
        asked.get(),
        1,
        "no image is made for a view that does not want it"
    );
}

#[test]
fn bad_display_addresses_and_preview_intervals_are_refused_before_the_render() {
    for (args, says) in [
        (vec!["--display", "localhost"], "no port"),
        (vec!["--display", ":14158"], "no host"),
        (vec!["--display", "127.0.0.1:0"], "no port"),
        (vec!["--display", "127.0.0.1:99999"], "no port"),
        (vec!["--preview=-1"], "--preview"),
        (vec!["--preview", "inf"], "--preview"),
    ] {
        let mut all = vec![
            "render",
            "--resolution",
            "8x8",
            "--spp",
            "100000",
            "-o",
            "/nonexistent-dir/x.exr",
        ];
        all.extend_from_slice(&args);
        let out = pathspace(&all);
        assert!(!out.status.success(), "{args:?}");
        assert!(stderr(&out).contains(says), "{args:?}: {}", stderr(&out));
        assert!(out.stdout.is_empty(), "{args:?}");
    }
}

#[test]
fn a_large_image_goes_as_strips_that_tev_puts_together() {
    let (w, h) = (700u32, 600u32);
    let mut image = Image::new(w, h);
    for (i, p) in image.pixels.iter_mut().enumerate() {
        *p = pathspace::spectrum::Rgb::new(i as f32, -(i as f32), 0.25 * i as f32);
    }
    let strips = display::strips(w, h);
    assert!(strips.len() > 1, "{strips:?}");
    let mut stream = Vec::new();
    for &(y0, y1) in &strips {
        let packet = display::update_image("big", &image, y0, y1);
        // tev holds a packet whole: a strip stays a few MiB
        assert!(packet.len() <= (5 << 20), "{}", packet.len());
        stream.extend(packet);
    }
    let mut canvas = vec![[f32::NAN; 3]; (w * h) as usize];
    for p in packets(&stream) {
        let Packet::Update {
            rect,
            offsets,
            strides,
            floats,
            ..
        } = p
        else {
            panic!("{p:?}");
        };
        apply(&mut canvas, w as usize, rect, &offsets, &strides, &floats);
    }
    let expected: Vec<[f32; 3]> = image.pixels.iter().map(|p| p.to_array()).collect();
    assert!(canvas == expected, "the strips cover the image once");
    assert_eq!(display::strips(1 << 20, 2).len(), 2, "at least a row each");
}

#[test]
fn a_viewer_that_stops_reading_is_dropped_and_the_render_goes_on() {
    // a listener that never accepts: the kernel takes the connection and buffers what it can,
    // then the client's writes block until its timeout
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let address = display::parse_address(&listener.local_addr().unwrap().to_string()).unwrap();
    let (w, h) = (2048, 2048); // 48 MiB a pass, more than any socket buffer
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut tev = display::Tev::new(address, "stalled");
        tev.start(w, h);
        assert!(tev.wants_image(), "the connection is open");
        tev.show(&Image::new(w, h));
        tx.send(tev.wants_image()).unwrap();
    });
    // a guard against a hang, not a time budget: the client gives up after seconds
    let wants = rx
        .recv_timeout(Duration::from_secs(120))
        .expect("a stalled viewer holds up the render");
    assert!(
        !wants,
        "the stalled viewer is dropped until the next attempt"
    );
    drop(listener);
}

//! `spectrum::cie` and the importer's `<spectrum>` reader (`scene::mitsuba::spectrum`) against
//! the colours Mitsuba 3.9.1 itself gives `<spectrum>` properties (recorded by
//! `scripts/spectrum_rgb.py` in `tests/fixtures/spectra/mitsuba.txt`): reflectances (bounded,
//! under D65), a conductor's index (unbounded, under D65), emission (unbounded, no D65, and a
//! uniform value's purplish sRGB) and a medium's coefficients (bounded), for lists inside, beyond
//! and within [360, 830] nm, with values above 1, and `.spd` files; bit for bit in f32, as the
//! importer writes them. Malformed lists and files are refused naming the problem.

use pathspace::scene::mitsuba::spectrum::{parse_spd, parse_value, read_spd, Spectrum};
use pathspace::spectrum::cie::{spectrum_list_to_srgb, Response};
use std::path::PathBuf;

fn fixtures() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/spectra")
}

/// (response, the spectrum as written, Mitsuba's f32 colour) of every recorded case.
fn recorded() -> Vec<(Response, String, [f32; 3])> {
    let text = std::fs::read_to_string(fixtures().join("mitsuba.txt")).unwrap();
    text.lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| {
            let f: Vec<&str> = l.split('|').collect();
            let response = match f[0] {
                "bounded" => Response::Bounded,
                "unbounded" => Response::Unbounded,
                "emissive" => Response::Emissive,
                r => panic!("unknown response {r}"),
            };
            let c: Vec<f32> = f[2].split(' ').map(|x| x.parse().unwrap()).collect();
            (response, f[1].to_string(), [c[0], c[1], c[2]])
        })
        .collect()
}

fn spectrum(written: &str) -> Spectrum {
    if written.ends_with(".spd") {
        read_spd(&fixtures().join(written)).unwrap()
    } else {
        parse_value(written).unwrap()
    }
}

#[test]
fn colours_are_mitsubas_bit_for_bit() {
    let cases = recorded();
    assert!(cases.len() >= 27, "{} cases", cases.len());
    let mut wrong = Vec::new();
    for (response, written, theirs) in &cases {
        let mine = spectrum(written).rgb(*response).0.as_vec3().to_array();
        if mine.map(f32::to_bits) != theirs.map(f32::to_bits) {
            wrong.push(format!(
                "{response:?} {written}: {mine:?} here, {theirs:?} in Mitsuba"
            ));
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

/// The flag says when Mitsuba warns "clamping out-of-gamut color": a bounded response above 1.
#[test]
fn clamping_is_reported() {
    let (w, v) = ([380.0, 480.0, 580.0, 780.0], [1.5, 0.2, 2.5, 0.7]);
    assert!(spectrum_list_to_srgb(&w, &v, Response::Bounded).1);
    assert!(!spectrum_list_to_srgb(&w, &v, Response::Unbounded).1);
    let (w, v) = ([400.0, 700.0], [0.5, 0.5]);
    assert!(!spectrum_list_to_srgb(&w, &v, Response::Bounded).1);
}

#[test]
fn values_and_files_are_read_as_mitsuba_reads_them() {
    assert_eq!(parse_value(" 0.25 ").unwrap(), Spectrum::Uniform(0.25));
    assert_eq!(
        parse_value("400:0.1,500:+0.5 600:7e-1").unwrap(),
        Spectrum::Pairs(vec![400.0, 500.0, 600.0], vec![0.1, 0.5, 0.7])
    );
    assert_eq!(
        parse_spd("# c\n\n400\t0.1\r\n500 0.5 # note\n").unwrap(),
        Spectrum::Pairs(vec![400.0, 500.0], vec![0.1, 0.5])
    );
}

#[test]
fn malformed_lists_are_refused_by_name() {
    for (text, needle) in [
        ("400:0.1", "at least two"),
        ("", "0 wavelength:value pairs"),
        ("500:0.1, 400:0.2", "must increase: 400 nm follows 500 nm"),
        ("400:0.1, 400:0.2", "must increase"),
        ("400:x, 500:0.1", "the value `x`"),
        ("nan:0.1, 500:0.1", "the wavelength `nan`"),
        ("400:inf, 500:0.1", "the value `inf`"),
        ("400:-0.1, 500:0.2", "negative"),
        (
            "400:0.1:3, 500:0.2",
            "`400:0.1:3` is not a wavelength:value pair",
        ),
        ("400, 500", "`400` is not a wavelength:value pair"),
        ("x", "the value `x`"),
    ] {
        let e = parse_value(text).expect_err(text);
        assert!(e.contains(needle), "{text}: `{e}` does not say {needle}");
    }
    for (text, needle) in [
        ("400 0.1\n500 0.2 0.3\n", "line 2: 3 fields"),
        ("400 0.1\n   \n500 0.2\n", "line 2: 0 fields"),
        ("400,0.1\n500 0.2\n", "line 1: 1 fields"),
        ("# only\n400 0.1\n", "at least two"),
        ("400 0.1\n300 0.2\n", "must increase"),
        ("400 0.1\n500 -2\n", "negative"),
    ] {
        let e = parse_spd(text).expect_err(text);
        assert!(e.contains(needle), "{text:?}: `{e}` does not say {needle}");
    }
    let e = read_spd(&fixtures().join("missing.spd")).unwrap_err();
    assert!(e.contains("No such file"), "{e}");
}

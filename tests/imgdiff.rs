//! `rayproof diff`: idiff metrics and verdict order, NaN/Inf rules, unreadable files, size
//! mismatches, HDR-ꟻLIP, the noise-aware z-test, and `run_diff`'s exit codes and files.

use crate::common::temp_dir;
use rayproof::images::*;
use std::path::Path;

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * b.abs().max(1e-300)
}

/// A w×h RGB image of one value.
fn flat(w: usize, h: usize, v: f32) -> Image {
    Image::rgb(w, h, vec![v; w * h * 3])
}

/// `img` with channel `c` of pixel (x, y) set to `v`.
fn with(mut img: Image, x: usize, y: usize, c: usize, v: f32) -> Image {
    let n = img.channels.len();
    img.data[(y * img.width + x) * n + c] = v;
    img
}

/// Deterministic pseudo-random numbers (SplitMix64), uniform in [0, 1).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Standard normal (Box–Muller).
    fn normal(&mut self) -> f64 {
        let (u, v) = (1.0 - self.next(), self.next());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// A smooth HDR test picture: a gradient up to ~4 with a bright (20) spot.
fn hdr_picture(w: usize, h: usize) -> Image {
    let mut data = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let g = 4.0 * (x + y) as f32 / (w + h) as f32;
            let spot = if (x as i32 - 8).pow(2) + (y as i32 - 8).pow(2) < 9 {
                20.0
            } else {
                0.0
            };
            data.extend([g + spot, 0.5 * g + spot, 0.25 + spot]);
        }
    }
    Image::rgb(w, h, data)
}

/// Whether `rayproof diff ARGS…` is refused as a usage error naming `option` (exit 64, one line).
fn usage_error(v: &[&str], option: &str) -> bool {
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .arg("diff")
        .args(v)
        .output()
        .expect("binary runs");
    let err = String::from_utf8_lossy(&o.stderr);
    o.status.code() == Some(64) && err.trim_end().lines().count() == 1 && err.contains(option)
}

/// `rayproof diff ARGS…`: its exit code.
fn run_diff(v: &[&str]) -> u8 {
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .arg("diff")
        .args(v)
        .output()
        .expect("binary runs");
    o.status.code().expect("exit code") as u8
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The single reason line of an Unreadable error naming `path`; panics on anything else.
fn unreadable(path: &Path) -> String {
    match read_image(path) {
        Err(e @ ImageError::Unreadable { .. }) => {
            let msg = e.to_string();
            assert_eq!(msg.lines().count(), 1, "{msg}");
            assert!(msg.contains(s(path)), "{msg}");
            assert_eq!(e.exit_code(), 4);
            msg
        }
        Ok(_) => panic!("{} was read", path.display()),
    }
}

// ---------------------------------------------------------------------------------------------
// Metrics against hand-computed values
// ---------------------------------------------------------------------------------------------

#[test]
fn metrics_2x2_by_hand() {
    // All 0.5; test (1,0).G = 1.0 (|d| = 0.5) and (0,1).R = 0.25 (|d| = 0.25); 12 samples.
    let r = flat(2, 2, 0.5);
    let t = with(with(flat(2, 2, 0.5), 1, 0, 1, 1.0), 0, 1, 0, 0.25);
    let c = compare(&r, &t, &Thresholds::default()).unwrap();
    // mean = 0.75/12 = 0.0625; RMS = sqrt((0.25 + 0.0625)/12) = 0.1613743060919757
    assert!(close(c.mean_error, 0.0625, 1e-12), "{}", c.mean_error);
    assert!(
        close(c.rms_error, 0.1613743060919757, 1e-12),
        "{}",
        c.rms_error
    );
    // peak = max(1, 1.0) = 1: PSNR = −20·log10(0.16137…) = 15.84331224367531
    assert_eq!(c.peak, 1.0);
    assert!(close(c.psnr, 15.84331224367531, 1e-12), "{}", c.psnr);
    // relMSE = (0.25/0.26 + 0.0625/0.26)/12 = 0.1001602564102564
    assert!(close(c.rel_mse, 0.1001602564102564, 1e-12), "{}", c.rel_mse);
    // max 0.5 at (1, 0, G), 0.5 vs 1
    assert_eq!(c.max_error, 0.5);
    assert_eq!((c.max_at, c.max_channel.as_str()), ((1, 0, 1), "G"));
    assert_eq!(c.max_values, (0.5, 1.0));
    assert_eq!((c.n_warn, c.n_fail, c.pixels), (2, 2, 4));
    assert_eq!(c.verdict, Verdict::Failure);

    let text = report_text("r.exr", "t.exr", &c, &Thresholds::default());
    let want = [
        "Comparing \"r.exr\" and \"t.exr\"",
        "  Mean error = 0.0625",
        "  RMS error = 0.161374",
        "  Peak SNR = 15.8433",
        "  Max error  = 0.5 @ (1, 0, G)  values are 0.5 vs 1",
        "  2 pixels (50%) over 1e-06",
        "  2 pixels (50%) over 1e-06",
        "  relMSE = 0.10016",
        "FAILURE",
    ];
    assert_eq!(text.lines().collect::<Vec<_>>(), want, "{text}");
}

#[test]
fn metrics_3x1_with_peak_above_one() {
    // ref (4,1,1) (0,0,0) (1,1,1); test differs at (1,0).B = 0.3 and (2,0).B = 3.0
    let r = Image::rgb(3, 1, vec![4.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
    let t = Image::rgb(3, 1, vec![4.0, 1.0, 1.0, 0.0, 0.0, 0.3, 1.0, 1.0, 3.0]);
    let c = compare(&r, &t, &Thresholds::default()).unwrap();
    // mean = 2.3/9; RMS = sqrt((0.09 + 4)/9) = 0.6741249472052228
    assert!(
        close(c.mean_error, 0.25555555555555554, 1e-7),
        "{}",
        c.mean_error
    );
    assert!(
        close(c.rms_error, 0.6741249472052228, 1e-7),
        "{}",
        c.rms_error
    );
    // peak = max(1, 4, 3) = 4: PSNR = 20·log10(4/0.67412…) = 15.46639184087908
    assert_eq!(c.peak, 4.0);
    assert!(close(c.psnr, 15.46639184087908, 1e-7), "{}", c.psnr);
    // relMSE = (0.09/0.01 + 4/1.01)/9 = 1.4400440044004401
    assert!(close(c.rel_mse, 1.4400440044004401, 1e-6), "{}", c.rel_mse);
    assert_eq!(
        (c.max_error, c.max_at, c.max_values),
        (2.0, (2, 0, 2), (1.0, 3.0))
    );
    assert_eq!(c.max_channel, "B");
    assert_eq!(c.n_fail, 2);
}

#[test]
fn identical_images_are_a_pass_with_infinite_psnr() {
    let a = hdr_picture(8, 4);
    let c = compare(&a, &a.clone(), &Thresholds::default()).unwrap();
    assert_eq!(
        (c.mean_error, c.rms_error, c.rel_mse, c.max_error),
        (0.0, 0.0, 0.0, 0.0)
    );
    assert_eq!(c.psnr, f64::INFINITY);
    assert_eq!((c.n_warn, c.n_fail, c.verdict), (0, 0, Verdict::Pass));
    let text = report_text("a", "b", &c, &Thresholds::default());
    assert!(
        text.contains("  Peak SNR = inf\n") && text.contains("  Max error  = 0\n"),
        "{text}"
    );
    assert!(text.ends_with("\nPASS\n"));
}

// ---------------------------------------------------------------------------------------------
// idiff's verdict order
// ---------------------------------------------------------------------------------------------

/// 10×10 = 100 pixels of 0.5, with `n` pixels (0..n, 0) off by `d` in R.
fn off_by(n: usize, d: f32) -> (Image, Image) {
    let r = flat(10, 10, 0.5);
    let t = (0..n).fold(r.clone(), |img, x| with(img, x, 0, 0, 0.5 + d));
    (r, t)
}

fn verdict_of(r: &Image, t: &Image, th: Thresholds) -> Verdict {
    compare(r, t, &th).unwrap().verdict
}

#[test]
fn allowfailures_passes_even_over_hardfail() {
    let (r, t) = off_by(1, 100.0);
    let th = Thresholds {
        hardfail: 1.0,
        hardwarn: 1.0,
        allowfailures: 1,
        ..Default::default()
    };
    assert_eq!(verdict_of(&r, &t, th), Verdict::Pass);
    assert_eq!(
        verdict_of(
            &r,
            &t,
            Thresholds {
                allowfailures: 0,
                ..th
            }
        ),
        Verdict::Failure
    );
    // two failing pixels are more than one allowed
    let (r2, t2) = off_by(2, 100.0);
    assert_eq!(verdict_of(&r2, &t2, th), Verdict::Failure);
}

#[test]
fn failpercent_under_is_not_failure_over_is() {
    let (r, t) = off_by(3, 0.1); // 3% of pixels fail
    let th = Thresholds {
        failpercent: 5.0,
        ..Default::default()
    };
    // under failpercent: not a failure, but 3 warnings > 0% → WARNING
    assert_eq!(verdict_of(&r, &t, th), Verdict::Warning);
    assert_eq!(
        verdict_of(
            &r,
            &t,
            Thresholds {
                warnpercent: 5.0,
                ..th
            }
        ),
        Verdict::Pass
    );
    assert_eq!(
        verdict_of(
            &r,
            &t,
            Thresholds {
                failpercent: 2.0,
                ..th
            }
        ),
        Verdict::Failure
    );
    // default failpercent 0: any failure beyond allowfailures fails
    assert_eq!(verdict_of(&r, &t, Thresholds::default()), Verdict::Failure);
}

#[test]
fn hardfail_fails_one_pixel_under_failpercent() {
    let (r, t) = off_by(1, 0.5);
    let th = Thresholds {
        failpercent: 5.0,
        warnpercent: 5.0,
        ..Default::default()
    };
    assert_eq!(verdict_of(&r, &t, th), Verdict::Pass);
    assert_eq!(
        verdict_of(
            &r,
            &t,
            Thresholds {
                hardfail: 0.4,
                ..th
            }
        ),
        Verdict::Failure
    );
    assert_eq!(
        verdict_of(
            &r,
            &t,
            Thresholds {
                hardfail: 0.6,
                ..th
            }
        ),
        Verdict::Pass
    );
    // hardwarn: the same pixel makes a WARNING
    assert_eq!(
        verdict_of(
            &r,
            &t,
            Thresholds {
                hardwarn: 0.4,
                ..th
            }
        ),
        Verdict::Warning
    );
    assert_eq!(
        verdict_of(
            &r,
            &t,
            Thresholds {
                hardwarn: 0.6,
                ..th
            }
        ),
        Verdict::Pass
    );
}

#[test]
fn warn_thresholds_count_separately_from_fail() {
    // 3 pixels off by 0.1: over warn 0.05, under fail 0.2 → no failures → PASS (rule 1)
    let (r, t) = off_by(3, 0.1);
    let th = Thresholds {
        warn: 0.05,
        fail: 0.2,
        ..Default::default()
    };
    let c = compare(&r, &t, &th).unwrap();
    assert_eq!((c.n_warn, c.n_fail, c.verdict), (3, 0, Verdict::Pass));
    // with 1 failing pixel tolerated by failpercent, the 3 warnings give WARNING
    let t2 = with(t, 5, 5, 1, 1.0);
    let th2 = Thresholds {
        failpercent: 1.0,
        ..th
    };
    let c = compare(&r, &t2, &th2).unwrap();
    assert_eq!((c.n_warn, c.n_fail, c.verdict), (4, 1, Verdict::Warning));
    assert_eq!(
        verdict_of(
            &r,
            &t2,
            Thresholds {
                warnpercent: 4.0,
                ..th2
            }
        ),
        Verdict::Pass
    );
}

#[test]
fn relative_thresholds() {
    // 10 vs 10.5: rel = 0.5/10.25 = 0.0488; 1 vs 1.5: rel = 0.5/1.25 = 0.4
    let r = Image::rgb(2, 1, vec![10.0, 10.0, 10.0, 1.0, 1.0, 1.0]);
    let t = Image::rgb(2, 1, vec![10.5, 10.0, 10.0, 1.5, 1.0, 1.0]);
    let th = Thresholds {
        failrelative: 0.1,
        warnrelative: 0.01,
        ..Default::default()
    };
    let c = compare(&r, &t, &th).unwrap();
    assert_eq!((c.n_warn, c.n_fail), (2, 1));
    let c = compare(
        &r,
        &t,
        &Thresholds {
            failrelative: 0.45,
            ..th
        },
    )
    .unwrap();
    assert_eq!(c.n_fail, 0);
    let c = compare(
        &r,
        &t,
        &Thresholds {
            failrelative: 0.04,
            ..th
        },
    )
    .unwrap();
    assert_eq!(c.n_fail, 2);
}

// ---------------------------------------------------------------------------------------------
// NaN and Inf
// ---------------------------------------------------------------------------------------------

#[test]
fn nan_equals_nan_and_inf_equals_inf() {
    let r = with(
        with(flat(2, 2, 0.5), 0, 0, 0, f32::NAN),
        1,
        1,
        2,
        f32::INFINITY,
    );
    let t = with(
        with(flat(2, 2, 0.5), 0, 0, 0, f32::NAN),
        1,
        1,
        2,
        f32::INFINITY,
    );
    let c = compare(&r, &t, &Thresholds::default()).unwrap();
    assert_eq!((c.max_error, c.mean_error, c.rel_mse), (0.0, 0.0, 0.0));
    assert_eq!(
        (c.n_fail, c.n_nonfinite_mismatch, c.verdict),
        (0, 0, Verdict::Pass)
    );
    // the peak ignores the infinity
    assert_eq!(c.peak, 1.0);
}

#[test]
fn nan_against_a_number_is_an_infinite_error_and_fails() {
    let r = flat(2, 2, 1.0);
    let t = with(flat(2, 2, 1.0), 1, 0, 2, f32::NAN);
    let c = compare(&r, &t, &Thresholds::default()).unwrap();
    assert_eq!(c.max_error, f64::INFINITY);
    assert_eq!((c.max_at, c.max_channel.as_str()), ((1, 0, 2), "B"));
    assert_eq!((c.n_fail, c.n_warn, c.n_nonfinite_mismatch), (1, 1, 1));
    assert_eq!(c.verdict, Verdict::Failure);
    // left out of the sums
    assert_eq!((c.mean_error, c.rms_error), (0.0, 0.0));
    let text = report_text("r", "t", &c, &Thresholds::default());
    assert!(
        text.contains("Max error  = inf @ (1, 0, B)  values are 1 vs NaN"),
        "{text}"
    );
    // JSON has no inf: written as a string
    let j = serde_json::to_value(&c).unwrap();
    assert_eq!(j["max_error"], "inf");
    assert_eq!(j["max_values"][1], "nan");
    // Whatever the percentages allow: one NaN in a 64×64 image is 0.02 % of the pixels
    let r = flat(64, 64, 1.0);
    let t = with(flat(64, 64, 1.0), 5, 7, 0, f32::NAN);
    let lax = Thresholds {
        failpercent: 100.0,
        warnpercent: 100.0,
        allowfailures: 0,
        ..Thresholds::default()
    };
    assert_eq!(compare(&r, &t, &lax).unwrap().verdict, Verdict::Failure);
    // idiff's own semantics (--idiff-compat) stay idiff's
    let c = rayproof::images::compare_as(&r, &t, &lax, rayproof::images::Semantics::Idiff).unwrap();
    assert_eq!(c.verdict, Verdict::Pass);
}

#[test]
fn opposite_infinities_and_inf_against_finite_mismatch() {
    let r = with(flat(2, 1, 0.0), 0, 0, 0, f32::INFINITY);
    let t = with(
        with(flat(2, 1, 0.0), 0, 0, 0, f32::NEG_INFINITY),
        1,
        0,
        1,
        f32::INFINITY,
    );
    let c = compare(&r, &t, &Thresholds::default()).unwrap();
    assert_eq!(
        (c.max_error, c.n_nonfinite_mismatch, c.n_fail),
        (f64::INFINITY, 2, 2)
    );
    // the first mismatch is the max location
    assert_eq!(c.max_at, (0, 0, 0));
}

// ---------------------------------------------------------------------------------------------
// Sizes
// ---------------------------------------------------------------------------------------------

#[test]
fn wrong_sizes_are_refused() {
    let e = compare(&flat(2, 2, 0.0), &flat(2, 3, 0.0), &Thresholds::default()).unwrap_err();
    assert_eq!(
        (e.reference.as_str(), e.test.as_str()),
        ("2x2 RGB", "2x3 RGB")
    );
    assert_eq!(e.exit_code(), 3);
    let rgba = Image::new(2, 2, &["R", "G", "B", "A"], vec![0.0; 16]);
    let e = compare(&flat(2, 2, 0.0), &rgba, &Thresholds::default()).unwrap_err();
    assert!(e.to_string().contains("2x2 RGBA"), "{e}");
    // same size: no error
    assert!(compare(&rgba, &rgba, &Thresholds::default()).is_ok());
}

// ---------------------------------------------------------------------------------------------
// Reading and writing
// ---------------------------------------------------------------------------------------------

#[test]
fn exr_and_png_round_trip() {
    let d = temp_dir("roundtrip");
    let img = hdr_picture(5, 3);
    write_exr_rgb(&d.join("a.exr"), &img).unwrap();
    assert_eq!(read_image(&d.join("a.exr")).unwrap(), img);

    let rgba = Image::new(
        2,
        1,
        &["R", "G", "B", "A"],
        vec![1., 2., 3., 0.5, 4., 5., 6., 1.],
    );
    write_exr_rgb(&d.join("a4.exr"), &rgba).unwrap();
    assert_eq!(read_image(&d.join("a4.exr")).unwrap(), rgba);

    // PNG: display-referred code values / 255; recognised by content, not by extension
    write_png_rgb8(&d.join("p.dat"), 3, 1, &[0, 128, 255, 1, 2, 3, 10, 20, 30]).unwrap();
    let p = read_image(&d.join("p.dat")).unwrap();
    assert!(p.display_referred);
    assert_eq!((p.width, p.height, p.channels.len()), (3, 1, 3));
    assert_eq!(&p.data[..3], &[0.0, 128.0 / 255.0, 1.0]);
    // no temporary files left behind
    let left: Vec<_> = std::fs::read_dir(&*d)
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert_eq!(left.len(), 3, "{left:?}");
}

#[test]
fn png_16_bit_grey_and_alpha() {
    let d = temp_dir("png16");
    let wide =
        image::ImageBuffer::<image::Rgb<u16>, _>::from_raw(1, 1, vec![0u16, 32768, 65535]).unwrap();
    wide.save_with_format(d.join("w.png"), image::ImageFormat::Png)
        .unwrap();
    let w = read_image(&d.join("w.png")).unwrap();
    // Code × (1/max) in float32, as OpenImageIO converts (idiff parity: tests/idiff_live.rs)
    let (i8, i16) = (1.0f32 / 255.0, 1.0f32 / 65535.0);
    assert_eq!(w.data, vec![0.0, 32768.0 * i16, 65535.0 * i16]);

    let grey = image::GrayImage::from_raw(2, 1, vec![51, 255]).unwrap();
    grey.save_with_format(d.join("g.png"), image::ImageFormat::Png)
        .unwrap();
    // Grey is one channel Y, as OpenImageIO reads it (idiff compares it as one)
    let g = read_image(&d.join("g.png")).unwrap();
    assert_eq!(g.channels, ["Y"]);
    let (c51, c255) = (51.0 * i8, 255.0 * i8);
    assert_eq!(g.data, vec![c51, c255]);
    let grey16 =
        image::ImageBuffer::<image::LumaA<u16>, _>::from_raw(1, 1, vec![32768u16, 65535]).unwrap();
    grey16
        .save_with_format(d.join("ga.png"), image::ImageFormat::Png)
        .unwrap();
    let ga = read_image(&d.join("ga.png")).unwrap();
    assert_eq!(ga.channels, ["Y", "A"]);
    assert_eq!(ga.data, vec![32768.0 * i16, 65535.0 * i16]);

    let rgba = image::RgbaImage::from_raw(1, 1, vec![255, 0, 0, 51]).unwrap();
    rgba.save_with_format(d.join("a.png"), image::ImageFormat::Png)
        .unwrap();
    let a = read_image(&d.join("a.png")).unwrap();
    assert_eq!(a.channels, ["R", "G", "B", "A"]);
    assert_eq!(a.data, vec![c255, 0.0, 0.0, c51]);
}

#[test]
fn exr_half_samples_extra_channels_and_missing_rgb() {
    use exr::prelude::*;
    let d = temp_dir("exrkinds");
    let ch = |name: &str, v: Vec<f32>| AnyChannel::new(name, FlatSamples::F32(v));
    let half = |name: &str, v: &[f32]| {
        AnyChannel::new(
            name,
            FlatSamples::F16(v.iter().map(|&x| f16::from_f32(x)).collect()),
        )
    };
    let write = |path: &Path, list: Vec<AnyChannel<FlatSamples>>| {
        let layer = Layer::new(
            (2, 1),
            LayerAttributes::default(),
            Encoding::UNCOMPRESSED,
            AnyChannels::sort(list.into()),
        );
        exr::prelude::Image::from_layer(layer)
            .write()
            .to_file(path)
            .unwrap();
    };
    // half R, G, B plus depth.Z: the unprefixed R, G, B layer read as f32 (the default: the
    // first layer with R, G, B), depth another layer
    write(
        &d.join("h.exr"),
        vec![
            half("R", &[0.5, 2.0]),
            half("G", &[0.25, 3.0]),
            half("B", &[1.0, 4.0]),
            ch("depth.Z", vec![7.0, 8.0]),
        ],
    );
    let h = read_image(&d.join("h.exr")).unwrap();
    assert_eq!(h.channels, ["R", "G", "B"]);
    assert_eq!(h.data, vec![0.5, 0.25, 1.0, 2.0, 3.0, 4.0]);
    let l = h.layer.as_ref().unwrap();
    assert_eq!((l.name.as_deref(), l.pick), (Some(""), LayerPick::FirstRgb));
    assert_eq!(l.layers, ["", "depth"]);
    let z = read_image_layer(&d.join("h.exr"), LayerSelect::Named("depth")).unwrap();
    assert_eq!(
        (z.channels.clone(), z.data.clone()),
        (vec!["Z".to_string()], vec![7.0, 8.0])
    );
    // only Y: one channel, compared as such
    write(&d.join("y.exr"), vec![ch("Y", vec![1.0, 2.0])]);
    let y = read_image(&d.join("y.exr")).unwrap();
    assert_eq!(
        (y.channels.clone(), y.data.clone(), y.layer.clone()),
        (vec!["Y".to_string()], vec![1.0, 2.0], None)
    );
    // two layers, neither Combined nor RGB: unreadable without --layer, and the message lists them
    write(
        &d.join("zn.exr"),
        vec![
            ch("depth.Z", vec![1.0, 2.0]),
            ch("normal.X", vec![0.0, 1.0]),
        ],
    );
    let msg = unreadable(&d.join("zn.exr"));
    assert!(
        msg.contains("--layer") && msg.contains("depth, normal"),
        "{msg}"
    );
}

#[test]
fn truncated_corrupt_empty_missing_files_are_unreadable() {
    let d = temp_dir("bad");
    write_exr_rgb(&d.join("ok.exr"), &hdr_picture(16, 16)).unwrap();
    let rgb8 = tonemap_rgb8(&hdr_picture(16, 16));
    write_png_rgb8(&d.join("ok.png"), 16, 16, &rgb8).unwrap();
    let mut rng = Rng(7);
    for ext in ["exr", "png"] {
        let good = std::fs::read(d.join(format!("ok.{ext}"))).unwrap();
        let n = good.len();
        // truncated: the first half
        let p = d.join(format!("half.{ext}"));
        std::fs::write(&p, &good[..n / 2]).unwrap();
        unreadable(&p);
        // truncated just after the magic bytes
        let p = d.join(format!("magic.{ext}"));
        std::fs::write(&p, &good[..8]).unwrap();
        unreadable(&p);
        // random bytes after the first 16 (the magic and the start of the header)
        let mut junk = good[..16].to_vec();
        junk.extend((16..n).map(|_| (rng.next() * 256.0) as u8));
        let p = d.join(format!("junk.{ext}"));
        std::fs::write(&p, &junk).unwrap();
        unreadable(&p);
        // every 5th byte after the magic flipped
        let mut flipped = good.clone();
        for b in flipped.iter_mut().skip(8).step_by(5) {
            *b ^= 0xff;
        }
        let p = d.join(format!("flipped.{ext}"));
        std::fs::write(&p, &flipped).unwrap();
        unreadable(&p);
    }
    std::fs::write(d.join("empty.exr"), b"").unwrap();
    assert!(unreadable(&d.join("empty.exr")).contains("empty"));
    std::fs::write(d.join("text.exr"), b"P3\n1 1\n255\n0 0 0\n").unwrap();
    assert!(unreadable(&d.join("text.exr")).contains("not an OpenEXR or PNG"));
    unreadable(&d.join("missing.exr"));
    unreadable(&d); // a directory
}

// ---------------------------------------------------------------------------------------------
// HDR-ꟻLIP
// ---------------------------------------------------------------------------------------------

#[test]
fn hdr_flip_identical_is_zero_and_different_is_not() {
    let r = hdr_picture(32, 32);
    let (m, map) = hdr_flip(&r, &r.clone());
    assert_eq!(m, 0.0);
    assert_eq!(map.len(), 32 * 32);
    assert!(map.iter().all(|&e| e == 0.0));

    // a bright square in the test
    let mut t = r.clone();
    for y in 16..24 {
        for x in 16..24 {
            for c in 0..3 {
                t = with(t, x, y, c, 6.0);
            }
        }
    }
    let (m, map) = hdr_flip(&r, &t);
    assert!(m > 0.01, "mean HDR-FLIP {m}");
    assert!(map.iter().all(|&e| (0.0..=1.0).contains(&e)));
    // the error sits on the square, not far from it
    assert!(map[20 * 32 + 20] > 0.1 && map[2 * 32 + 30] < 0.01);
}

#[test]
fn hdr_flip_follows_the_reference_exposure() {
    let r = hdr_picture(32, 32);
    let t = with(with(r.clone(), 20, 20, 0, 9.0), 5, 25, 1, 0.0);
    let scaled = |img: &Image| Image {
        data: img.data.iter().map(|v| v * 2.0).collect(),
        ..img.clone()
    };
    let (m1, _) = hdr_flip(&r, &t);
    let (m2, _) = hdr_flip(&scaled(&r), &scaled(&t));
    assert!(m1 > 1e-4, "{m1}");
    assert!((m1 - m2).abs() < 1e-3 * m1, "{m1} vs {m2}");
}

#[test]
fn hdr_flip_black_and_nonfinite_inputs() {
    let z = flat(8, 8, 0.0);
    assert_eq!(hdr_flip(&z, &z.clone()).0, 0.0);
    // black reference, lit test: an error
    let (m, _) = hdr_flip(&z, &flat(8, 8, 0.5));
    assert!(m > 0.1, "{m}");
    // NaN/Inf count as 0 for FLIP only: no NaN in the result
    let bad = with(
        with(flat(8, 8, 1.0), 1, 1, 0, f32::NAN),
        2,
        2,
        1,
        f32::INFINITY,
    );
    let (m, map) = hdr_flip(&flat(8, 8, 1.0), &bad);
    assert!(
        m.is_finite() && m > 0.0 && map.iter().all(|e| e.is_finite()),
        "{m}"
    );
}

#[test]
fn flip_error_uses_ldr_for_two_pngs() {
    let mut a = flat(16, 16, 0.5);
    a.display_referred = true;
    let mut b = with(a.clone(), 3, 3, 0, 1.0);
    b.display_referred = true;
    let (kind, m, _) = flip_error(&a, &b);
    assert_eq!(kind, FlipKind::Ldr);
    assert!(m > 0.0);
    assert_eq!(flip_error(&a, &a.clone()).1, 0.0);
    assert_eq!(
        flip_error(&flat(4, 4, 0.5), &flat(4, 4, 0.5)).0,
        FlipKind::Hdr
    );
}

#[test]
fn heatmap_and_tonemap_bytes() {
    let h = heatmap_rgb8(&[0.0, 1.0, f32::NAN, 7.0], 2, 2);
    assert_eq!(h.len(), 12);
    // magma: black-ish at 0, light at 1; NaN and >1 shown as 1
    assert!(h[..3].iter().all(|&v| v < 10) && h[3..6].iter().map(|&v| v as u32).sum::<u32>() > 500);
    assert_eq!(&h[6..9], &h[3..6]);
    assert_eq!(&h[9..12], &h[3..6]);
    let img = Image::rgb(2, 1, vec![0.0, 1.0, 5.0, -1.0, f32::NAN, 0.214]);
    assert_eq!(tonemap_rgb8(&img), vec![0, 255, 255, 0, 0, 127]);
}

// ---------------------------------------------------------------------------------------------
// Noise-aware z-test
// ---------------------------------------------------------------------------------------------

/// 64×64 reference with a constant per-channel variance.
fn noisy_setup(var: f32) -> (Image, Image) {
    (hdr_picture(64, 64), flat(64, 64, var))
}

#[test]
fn z_test_identical_passes() {
    let (r, v) = noisy_setup(0.01);
    let z = z_test(&r, &r.clone(), &v, &ZParams::default()).unwrap();
    assert_eq!(
        (z.verdict, z.failing_pixels, z.min_p),
        (Verdict::Pass, 0, 1.0)
    );
    // Šidák: 1 − 0.99^(1/4096)
    assert!(
        close(z.alpha, 1.0 - 0.99f64.powf(1.0 / 4096.0), 1e-9),
        "{}",
        z.alpha
    );
}

#[test]
fn z_test_gaussian_noise_passes_where_idiff_fails() {
    let (r, v) = noisy_setup(0.01); // σ = 0.1
    let mut rng = Rng(11);
    let t = Image {
        data: r
            .data
            .iter()
            .map(|&x| x + 0.1 * rng.normal() as f32)
            .collect(),
        ..r.clone()
    };
    let z = z_test(&r, &t, &v, &ZParams::default()).unwrap();
    assert_eq!(z.verdict, Verdict::Pass, "{z:?}");
    assert_eq!(
        compare(&r, &t, &Thresholds::default()).unwrap().verdict,
        Verdict::Failure
    );
}

#[test]
fn z_test_offset_by_ten_sigma_fails() {
    let (r, v) = noisy_setup(0.01);
    let t = Image {
        data: r.data.iter().map(|&x| x + 1.0).collect(),
        ..r.clone()
    };
    let z = z_test(&r, &t, &v, &ZParams::default()).unwrap();
    assert_eq!(
        (z.verdict, z.failing_pixels, z.passing_channels),
        (Verdict::Failure, 4096, 0)
    );
    // p = erfc(10/√2) ≈ 1.5e−23
    assert!(z.min_p < 1e-20, "{}", z.min_p);
}

#[test]
fn z_test_one_outlier_passes_many_fail() {
    let (r, v) = noisy_setup(0.01);
    let one = with(r.clone(), 10, 10, 1, 50.0);
    let z = z_test(&r, &one, &v, &ZParams::default()).unwrap();
    assert_eq!((z.verdict, z.failing_pixels), (Verdict::Pass, 1));
    assert_eq!((z.min_p_at, z.min_p_channel.as_str()), ((10, 10, 1), "G"));
    // 11 bad pixels × 3 channels = 33 > 0.25% of 12288 channel tests (30.72)
    let many = (0..11).fold(r.clone(), |img, x| {
        (0..3).fold(img, |i, c| with(i, x, 0, c, 50.0))
    });
    let z = z_test(&r, &many, &v, &ZParams::default()).unwrap();
    assert_eq!((z.verdict, z.failing_pixels), (Verdict::Failure, 11));
    // 10 such pixels (30 channels) still pass
    let ten = (0..10).fold(r.clone(), |img, x| {
        (0..3).fold(img, |i, c| with(i, x, 0, c, 50.0))
    });
    assert_eq!(
        z_test(&r, &ten, &v, &ZParams::default()).unwrap().verdict,
        Verdict::Pass
    );
}

#[test]
fn z_test_spp_scales_the_variance() {
    // per-sample variance 1; offset 0.5: z = 0.5 at 1 spp, 5 at 100 spp (p = 5.7e−7 < α)
    let (r, v) = noisy_setup(1.0);
    let t = Image {
        data: r.data.iter().map(|&x| x + 0.5).collect(),
        ..r.clone()
    };
    let at = |spp| {
        z_test(
            &r,
            &t,
            &v,
            &ZParams {
                spp,
                ..Default::default()
            },
        )
        .unwrap()
    };
    // Per pixel: z = 0.5 passes at 1 spp, z = 5 fails at 100
    assert_eq!((at(1).failing_pixels, at(100).failing_pixels), (0, 4096));
    assert_eq!(at(100).verdict, Verdict::Failure);
    // But every pixel 0.5 σ up is a shift of the image's mean: 0.5·sqrt(4096) = 32 σ of it
    let one = at(1);
    assert_eq!(one.verdict, Verdict::Failure);
    assert!(
        one.shift_z.iter().all(|z| (z - 32.0).abs() < 3.0),
        "{:?}",
        one.shift_z
    );
}

#[test]
fn z_test_variance_must_match() {
    let r = hdr_picture(8, 8);
    assert!(z_test(&r, &r.clone(), &flat(8, 4, 1.0), &ZParams::default()).is_err());
    let only_r = Image::new(8, 8, &["R"], vec![1.0; 64]);
    assert!(z_test(&r, &r.clone(), &only_r, &ZParams::default()).is_err());
    // RGBA variance for an RGB image is fine
    let rgba = Image::new(8, 8, &["R", "G", "B", "A"], vec![1.0; 256]);
    assert!(z_test(&r, &r.clone(), &rgba, &ZParams::default()).is_ok());
}

// ---------------------------------------------------------------------------------------------
// run_diff
// ---------------------------------------------------------------------------------------------

#[test]
fn run_diff_exit_codes() {
    let d = temp_dir("exit");
    let r = hdr_picture(16, 16);
    write_exr_rgb(&d.join("r.exr"), &r).unwrap();
    write_exr_rgb(&d.join("same.exr"), &r).unwrap();
    write_exr_rgb(&d.join("t.exr"), &with(r.clone(), 3, 3, 0, 9.0)).unwrap();
    write_exr_rgb(&d.join("small.exr"), &flat(16, 8, 1.0)).unwrap();
    let (rp, tp) = (d.join("r.exr"), d.join("t.exr"));
    let run = |v: &[&str]| run_diff(v);
    assert_eq!(run(&["-q", s(&rp), s(&d.join("same.exr"))]), 0);
    assert_eq!(run(&["-q", "--no-flip", s(&rp), s(&tp)]), 2);
    // one pixel in 256 is 0.39%: under failpercent 1 → warning; with warnpercent 1 → pass
    assert_eq!(
        run(&["-q", "--no-flip", "--failpercent", "1", s(&rp), s(&tp)]),
        1
    );
    let all = [
        "-q",
        "--no-flip",
        "--failpercent",
        "1",
        "--warnpercent",
        "1",
        s(&rp),
        s(&tp),
    ];
    assert_eq!(run(&all), 0);
    assert_eq!(
        run(&["-q", "--no-flip", "--allowfailures", "1", s(&rp), s(&tp)]),
        0
    );
    assert_eq!(run(&["-q", s(&rp), s(&d.join("small.exr"))]), 3);
    assert_eq!(run(&["-q", s(&rp), s(&d.join("nope.exr"))]), 4);
    std::fs::write(d.join("half.exr"), &std::fs::read(&rp).unwrap()[..100]).unwrap();
    assert_eq!(run(&["-q", s(&d.join("half.exr")), s(&tp)]), 4);
}

#[test]
fn run_diff_writes_json_diff_exr_and_heatmap() {
    let d = temp_dir("files");
    let r = hdr_picture(16, 8);
    let t = with(with(r.clone(), 3, 2, 1, 7.0), 4, 4, 2, f32::NAN);
    write_exr_rgb(&d.join("r.exr"), &r).unwrap();
    write_exr_rgb(&d.join("t.exr"), &t).unwrap();
    let (j, x, h) = (d.join("out.json"), d.join("diff.exr"), d.join("heat.png"));
    let code = run_diff(&[
        "-q",
        "--json",
        s(&j),
        "--diff-exr",
        s(&x),
        "--heatmap",
        s(&h),
        s(&d.join("r.exr")),
        s(&d.join("t.exr")),
    ]);
    assert_eq!(code, 2);
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&j).unwrap()).unwrap();
    assert_eq!(
        (v["verdict"].as_str(), v["exit_code"].as_u64()),
        (Some("failure"), Some(2))
    );
    let c = &v["comparison"];
    assert_eq!(
        (c["n_fail"].as_u64(), c["n_nonfinite_mismatch"].as_u64()),
        (Some(2), Some(1))
    );
    assert_eq!(c["max_error"], "inf");
    assert_eq!(c["flip_kind"], "hdr");
    assert!(c["flip_mean"].as_f64().unwrap() > 0.0);
    assert_eq!(v["thresholds"]["hardfail"], "inf");
    assert!(v["ztest"].is_null());

    // |d|: 7 − G at (3, 2); NaN mismatch → inf; elsewhere 0
    let dx = read_image(&x).unwrap();
    let at = |x: usize, y: usize, c: usize| dx.data[(y * 16 + x) * 3 + c];
    assert_eq!(at(3, 2, 1), (7.0 - r.data[(2 * 16 + 3) * 3 + 1]).abs());
    assert_eq!(at(4, 4, 2), f32::INFINITY);
    assert_eq!(at(0, 0, 0), 0.0);
    let heat = read_image(&h).unwrap();
    assert_eq!((heat.width, heat.height), (16, 8));
    let names: Vec<_> = std::fs::read_dir(&*d)
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert_eq!(names.len(), 5, "leftover temporary files: {names:?}");
}

#[test]
fn run_diff_variance_mode_and_no_flip_heatmap() {
    let d = temp_dir("variance");
    let r = hdr_picture(32, 32);
    let t = Image {
        data: r.data.iter().map(|&x| x + 0.01).collect(),
        ..r.clone()
    };
    write_exr_rgb(&d.join("r.exr"), &r).unwrap();
    write_exr_rgb(&d.join("t.exr"), &t).unwrap();
    write_exr_rgb(&d.join("v.exr"), &flat(32, 32, 0.01)).unwrap();
    write_exr_rgb(&d.join("v_small.exr"), &flat(16, 32, 0.01)).unwrap();
    let (rp, tp, vp, j) = (
        d.join("r.exr"),
        d.join("t.exr"),
        d.join("v.exr"),
        d.join("z.json"),
    );
    let base = ["-q", "--no-flip", s(&rp), s(&tp), "--variance"];
    // 0.01 off with σ = 0.1: the z-test passes although idiff would fail
    let mut args = base.to_vec();
    args.extend([s(&vp), "--json", s(&j)]);
    assert_eq!(run_diff(&args), 0);
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&j).unwrap()).unwrap();
    assert_eq!(v["verdict"], "pass");
    assert_eq!(v["comparison"]["verdict"], "failure");
    assert_eq!(v["ztest"]["params"]["spp"], 1);
    assert!(v["comparison"]["flip_mean"].is_null());
    // 10⁴ spp: σ of the mean 0.001, the offset is 10σ
    let mut args = base.to_vec();
    args.extend([s(&vp), "--spp", "10000"]);
    assert_eq!(run_diff(&args), 2);
    // variance of another size
    let small = d.join("v_small.exr");
    let mut args = base.to_vec();
    args.push(s(&small));
    assert_eq!(run_diff(&args), 3);
    // --spp needs --variance; bad significance is a usage error
    assert!(usage_error(&[s(&rp), s(&tp), "--spp", "4"], "--variance"));
    let bad = [
        s(&rp),
        s(&tp),
        "--variance",
        s(&vp),
        "--significance",
        "1.5",
    ];
    assert!(usage_error(&bad, "--significance"));
    assert!(usage_error(&[s(&rp), s(&tp), "--fail", "nan"], "--fail"));
    // `--hardfail inf` is accepted (not a usage error naming the option)
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .args(["diff", "-q", s(&rp), s(&tp), "--hardfail", "inf"])
        .output()
        .unwrap();
    assert!(
        !String::from_utf8_lossy(&o.stderr).contains("--hardfail"),
        "{o:?}"
    );

    // --no-flip heat map: largest |d| × 16 = 0.16 everywhere → one colour
    let h = d.join("h.png");
    assert_eq!(
        run_diff(&["-q", "--no-flip", "--heatmap", s(&h), s(&rp), s(&tp)]),
        2
    );
    let heat = read_image(&h).unwrap();
    assert!(heat.data.chunks(3).all(|p| p == &heat.data[..3]));
    let want = heatmap_rgb8(&[0.16], 1, 1);
    assert_eq!(tonemap_rgb8(&heat)[..3], want[..]);
}

#[test]
fn run_diff_checks_outputs_before_work() {
    let d = temp_dir("outputs");
    let r = hdr_picture(8, 8);
    write_exr_rgb(&d.join("r.exr"), &r).unwrap();
    let rp = d.join("r.exr");
    let nowhere = d.join("no/such/dir/out.json");
    // the inputs are missing too: the output check comes first (73, not 4)
    let code = run_diff(&[
        "--json",
        s(&nowhere),
        s(&d.join("x.exr")),
        s(&d.join("y.exr")),
    ]);
    assert_eq!(code, 73);
    assert!(!d.join("no").exists());
    // an output may not overwrite an input
    assert_eq!(run_diff(&["-q", "--diff-exr", s(&rp), s(&rp), s(&rp)]), 73);
    assert_eq!(read_image(&rp).unwrap(), r);
    // a directory is not an output file
    assert_eq!(run_diff(&["-q", "--heatmap", s(&d), s(&rp), s(&rp)]), 73);
    // one file named as two outputs: refused, and the file there stays as it was (the previous
    // binary wrote the heat map, then the JSON over it)
    let both = d.join("both.png");
    std::fs::write(&both, b"old").unwrap();
    let o = rayproof_diff(&["--heatmap", s(&both), "--json", s(&both), s(&rp), s(&rp)]);
    assert_one_line_error(&o, 73, "two outputs");
    assert_eq!(std::fs::read(&both).unwrap(), b"old");
    // the outputs of a run are committed together: none is left behind beside the old file
    let left: Vec<_> = std::fs::read_dir(&*d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("rayproof"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

// ---------------------------------------------------------------------------------------------
// The binary
// ---------------------------------------------------------------------------------------------

fn rayproof_diff(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .arg("diff")
        .args(args)
        .output()
        .expect("binary runs")
}

/// Exit `code`, and exactly one line on stderr naming `what`, no panic.
fn assert_one_line_error(o: &std::process::Output, code: i32, what: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(code), "stderr: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(
        err.starts_with("error") && err.contains(what),
        "'{what}' not in: {err}"
    );
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn binary_report_note_json_and_errors() {
    let d = temp_dir("binary");
    let r = hdr_picture(16, 16);
    write_exr_rgb(&d.join("r.exr"), &r).unwrap();
    write_exr_rgb(&d.join("s.exr"), &flat(8, 8, 0.0)).unwrap();
    write_png_rgb8(&d.join("t.png"), 16, 16, &tonemap_rgb8(&r)).unwrap();
    std::fs::write(d.join("bad.exr"), b"v/1\x01 not really").unwrap();
    let (rp, tp) = (
        s(&d.join("r.exr")).to_string(),
        s(&d.join("t.png")).to_string(),
    );

    // By default no ꟻLIP (issue 46: it cost 7× idiff's CPU): not in the report
    let o = rayproof_diff(&[&rp, &rp]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(!out.contains("FLIP") && out.ends_with("\nPASS\n"), "{out}");

    // identical, ꟻLIP asked for: the full report, then PASS
    let o = rayproof_diff(&["--flip", &rp, &rp]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(0), "{out}");
    assert!(
        out.starts_with(&format!("Comparing \"{rp}\" and \"{rp}\"\n")),
        "{out}"
    );
    assert!(
        out.contains("  Mean HDR-FLIP = 0\n") && out.ends_with("\nPASS\n"),
        "{out}"
    );

    // EXR against PNG: a note, and a failure
    let o = rayproof_diff(&["--no-flip", &rp, &tp]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(2), "{out}");
    assert!(
        out.starts_with("note: ") && out.contains("display-referred (PNG)"),
        "{out}"
    );
    assert!(
        !out.contains("FLIP") && out.ends_with("\nFAILURE\n"),
        "{out}"
    );

    // --json -: only JSON on stdout
    let o = rayproof_diff(&["--json", "-", &rp, &rp]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON only");
    assert_eq!(
        (o.status.code(), v["verdict"].as_str()),
        (Some(0), Some("pass"))
    );

    // -q: the verdict line alone
    let o = rayproof_diff(&["-q", "--no-flip", &rp, &tp]);
    assert_eq!(String::from_utf8_lossy(&o.stdout), "FAILURE\n");

    // errors: one line naming the culprit
    assert_one_line_error(
        &rayproof_diff(&[&rp, s(&d.join("s.exr"))]),
        3,
        "size mismatch",
    );
    assert_one_line_error(&rayproof_diff(&[&rp, s(&d.join("bad.exr"))]), 4, "bad.exr");
    assert_one_line_error(
        &rayproof_diff(&[s(&d.join("none.png")), &rp]),
        4,
        "none.png",
    );
    assert_one_line_error(&rayproof_diff(&[&rp, &rp, "--fail=-1"]), 64, "--fail");
    let nowhere = d.join("no/dir/h.png");
    assert_one_line_error(
        &rayproof_diff(&["--heatmap", s(&nowhere), &rp, &rp]),
        73,
        "no/dir",
    );
}

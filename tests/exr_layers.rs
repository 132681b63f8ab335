//! EXR files as renderers write them, without outside tools (fast; `tests/idiff_live.rs` proves
//! the same against the real idiff): Blender's multilayer channels and the layer `diff` picks,
//! single-channel images, data and display windows.

use crate::common::{temp_dir, write_exr as write};
use rayproof::images::*;
use std::path::Path;
use std::process::Command;

/// A full frame at (0, 0).
fn frame(w: usize, h: usize) -> ((i32, i32), (usize, usize)) {
    ((0, 0), (w, h))
}

/// `rayproof diff ARGS`: exit code, stdout, stderr.
fn diff(dir: &Path, args: &[&str]) -> (i32, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .arg("diff")
        .args(args)
        .arg("--no-flip")
        .current_dir(dir)
        .output()
        .unwrap();
    (
        o.status.code().unwrap(),
        String::from_utf8_lossy(&o.stdout).into(),
        String::from_utf8_lossy(&o.stderr).into(),
    )
}

/// Blender's passes: AO (RGB, before Combined in the file's order), Combined (RGBA), Depth (Z).
fn blender(path: &Path, combined_r: f32, depth: f32) {
    write(
        path,
        (4, 3),
        (0, 0),
        frame(4, 3),
        &[
            ("ViewLayer.AO.R", vec![0.1]),
            ("ViewLayer.AO.G", vec![0.1]),
            ("ViewLayer.AO.B", vec![0.1]),
            ("ViewLayer.Combined.R", vec![combined_r]),
            ("ViewLayer.Combined.G", vec![0.6]),
            ("ViewLayer.Combined.B", vec![0.7]),
            ("ViewLayer.Combined.A", vec![1.0]),
            ("ViewLayer.Depth.Z", vec![depth]),
        ],
    );
}

#[test]
fn the_combined_layer_is_compared_by_default_and_said() {
    let d = temp_dir("combined");
    blender(&d.join("a.exr"), 0.5, 7.0);
    let a = read_image(&d.join("a.exr")).unwrap();
    assert_eq!(a.channels, ["R", "G", "B", "A"]);
    assert_eq!(&a.data[..4], &[0.5, 0.6, 0.7, 1.0]);
    let l = a.layer.clone().unwrap();
    assert_eq!(
        (l.name.as_deref(), l.pick),
        (Some("ViewLayer.Combined"), LayerPick::Combined)
    );
    assert_eq!(
        l.layers,
        ["ViewLayer.AO", "ViewLayer.Combined", "ViewLayer.Depth"]
    );
    // By name, whole or its end
    let z = read_image_layer(&d.join("a.exr"), LayerSelect::Named("Depth")).unwrap();
    assert_eq!(
        (z.channels.clone(), z.data[0]),
        (vec!["Z".to_string()], 7.0)
    );
    let ao = read_image_layer(&d.join("a.exr"), LayerSelect::Named("ViewLayer.AO")).unwrap();
    assert_eq!((ao.channels.len(), ao.data[0]), (3, 0.1));
    let e = read_image_layer(&d.join("a.exr"), LayerSelect::Named("Normal")).unwrap_err();
    assert!(
        e.to_string().contains(
            "no layer 'Normal' (its layers: ViewLayer.AO, ViewLayer.Combined, ViewLayer.Depth)"
        ),
        "{e}"
    );
    // As idiff: every channel, in OpenImageIO's order
    let all = read_image_layer(&d.join("a.exr"), LayerSelect::AsIdiff).unwrap();
    assert_eq!(
        all.channels[3..7],
        [
            "ViewLayer.Combined.R",
            "ViewLayer.Combined.G",
            "ViewLayer.Combined.B",
            "ViewLayer.Combined.A"
        ]
    );
    assert_eq!(all.layer.unwrap().pick, LayerPick::All);

    // The command line: a change in Depth alone passes the default (Combined) comparison and
    // says so; --layer Depth fails; --idiff-compat compares every channel
    blender(&d.join("b.exr"), 0.5, 7.5);
    let (code, out, _) = diff(&d, &["a.exr", "b.exr"]);
    assert_eq!(code, 0, "{out}");
    assert!(
        out.contains("Layer: ViewLayer.Combined, in both files (the default: a Combined layer"),
        "{out}"
    );
    let (code, out, _) = diff(&d, &["a.exr", "b.exr", "--layer", "Depth"]);
    assert_eq!(code, 2, "{out}");
    assert!(
        out.contains("@ (0, 0, Z)") && out.contains("named by --layer"),
        "{out}"
    );
    let (code, out, _) = diff(&d, &["a.exr", "b.exr", "--idiff-compat"]);
    assert_eq!(code, 2, "{out}");
    assert!(out.contains("@ (0, 0, ViewLayer.Depth.Z)"), "{out}");
    // The JSON names the layer of each image
    let (_, out, _) = diff(&d, &["a.exr", "b.exr", "--json", "-"]);
    let j: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(j["comparison"]["layers"][1]["name"], "ViewLayer.Combined");
    assert_eq!(j["comparison"]["layers"][1]["pick"], "combined");
    // A change in Combined fails by default, at its channel
    blender(&d.join("c.exr"), 0.25, 7.0);
    let (code, out, _) = diff(&d, &["a.exr", "c.exr"]);
    assert_eq!(code, 2, "{out}");
    assert!(out.contains("Max error  = 0.25 @ (0, 0, R)"), "{out}");
}

#[test]
fn without_combined_the_first_rgb_layer_and_layers_that_differ_are_refused() {
    let d = temp_dir("firstrgb");
    let rgb = |p: &str, v: f32| -> Vec<(String, Vec<f32>)> {
        ["R", "G", "B"]
            .iter()
            .map(|c| (format!("{p}.{c}"), vec![v]))
            .collect()
    };
    let chans = |v: Vec<(String, Vec<f32>)>, p: &Path| {
        let v: Vec<(&str, Vec<f32>)> = v.iter().map(|(n, x)| (n.as_str(), x.clone())).collect();
        write(p, (2, 2), (0, 0), frame(2, 2), &v);
    };
    // Depth.Z and Emit.RGB: the first with R, G, B (Emit), not the first layer
    let mut v = vec![("Depth.Z".to_string(), vec![3.0])];
    v.extend(rgb("Emit", 0.25));
    chans(v, &d.join("e.exr"));
    let e = read_image(&d.join("e.exr")).unwrap();
    let l = e.layer.unwrap();
    assert_eq!(
        (l.name.as_deref(), l.pick),
        (Some("Emit"), LayerPick::FirstRgb)
    );
    // Two view layers: both Combined layers compared (a change in the second is never passed
    // over), and "Combined" alone is ambiguous
    let mut v = rgb("A.Combined", 0.5);
    v.extend(rgb("B.Combined", 0.75));
    chans(v, &d.join("ab.exr"));
    let ab = read_image(&d.join("ab.exr")).unwrap();
    let l = ab.layer.unwrap();
    assert_eq!((l.name.as_deref(), l.pick), (None, LayerPick::Every));
    assert_eq!(ab.channels.len(), 6);
    let err = read_image_layer(&d.join("ab.exr"), LayerSelect::Named("Combined")).unwrap_err();
    assert!(
        err.to_string().contains("names several of its layers"),
        "{err}"
    );
    // Layers of two names are two images: refused (exit 3), naming both
    chans(rgb("Other.Combined", 0.5), &d.join("o.exr"));
    let (code, _, err) = diff(&d, &["ab.exr", "o.exr"]);
    assert_eq!(code, 3, "{err}");
    assert!(
        err.contains("A.Combined.R,A.Combined.G") && err.contains("(layer Other.Combined)"),
        "{err}"
    );
    // Several layers, none Combined or RGB: refused with the list (exit 4)
    chans(
        vec![
            ("Depth.Z".into(), vec![1.0]),
            ("Normal.X".into(), vec![0.0]),
        ],
        &d.join("zn.exr"),
    );
    let (code, _, err) = diff(&d, &["zn.exr", "zn.exr"]);
    assert_eq!(code, 4, "{err}");
    assert!(
        err.contains("choose one with --layer (its layers: Depth, Normal)"),
        "{err}"
    );
    assert_eq!(diff(&d, &["zn.exr", "zn.exr", "--layer", "Normal"]).0, 0);
}

#[test]
fn single_channel_images_compare_as_one_channel() {
    let d = temp_dir("single");
    for name in ["R", "Y", "Z"] {
        let (a, b) = (
            d.join(format!("{name}1.exr")),
            d.join(format!("{name}2.exr")),
        );
        write(&a, (3, 2), (0, 0), frame(3, 2), &[(name, vec![0.5])]);
        let mut plane = vec![0.5; 6];
        plane[4] = 0.75;
        write(&b, (3, 2), (0, 0), frame(3, 2), &[(name, plane)]);
        let (ia, ib) = (read_image(&a).unwrap(), read_image(&b).unwrap());
        assert_eq!(
            (ia.channels.clone(), ia.layer.clone()),
            (vec![name.to_string()], None)
        );
        let c = compare(&ia, &ib, &Thresholds::default()).unwrap();
        // One channel: the mean is over 6 samples, the maximum at (1, 1) in it
        assert_eq!(
            (c.n_fail, c.mean_error, c.max_at),
            (1, 0.25 / 6.0, (1, 1, 0)),
            "{name}"
        );
        assert_eq!(c.max_channel, name);
    }
    // A grey PNG: one channel Y, against a grey PNG
    let grey = image::GrayImage::from_raw(2, 1, vec![10, 20]).unwrap();
    grey.save(d.join("g.png")).unwrap();
    let g = read_image(&d.join("g.png")).unwrap();
    assert_eq!(g.channels, ["Y"]);
    let (code, out, _) = diff(&d, &["g.png", "g.png"]);
    assert_eq!(code, 0, "{out}");
}

#[test]
fn data_windows_are_placed_and_compared_over_their_union() {
    let d = temp_dir("windows");
    // An 8×6 frame; a 4×3 data window at (2, 2) holding the frame's pixels there
    let pixel = |x: usize, y: usize| (y * 8 + x) as f32 / 100.0;
    let full: Vec<f32> = (0..48).map(|i| pixel(i % 8, i / 8)).collect();
    let crop: Vec<f32> = (0..12).map(|i| pixel(2 + i % 4, 2 + i / 4)).collect();
    let inside = |i: usize| (2..6).contains(&(i % 8)) && (2..5).contains(&(i / 8));
    let full_zero_outside: Vec<f32> = (0..48)
        .map(|i| if inside(i) { full[i] } else { 0.0 })
        .collect();
    write(
        &d.join("full.exr"),
        (8, 6),
        (0, 0),
        frame(8, 6),
        &[("Y", full.clone())],
    );
    write(
        &d.join("fz.exr"),
        (8, 6),
        (0, 0),
        frame(8, 6),
        &[("Y", full_zero_outside)],
    );
    write(
        &d.join("crop.exr"),
        (4, 3),
        (2, 2),
        frame(8, 6),
        &[("Y", crop.clone())],
    );
    let c = read_image(&d.join("crop.exr")).unwrap();
    assert_eq!(
        (c.origin, c.width, c.display),
        ((2, 2), 4, Window::at_origin(8, 6))
    );
    // The crop is the frame with 0 outside its data window: equal (rayproof and idiff alike)
    let fz = read_image(&d.join("fz.exr")).unwrap();
    for s in [Semantics::Rayproof, Semantics::Idiff] {
        let r = compare_as(&c, &fz, &Thresholds::default(), s).unwrap();
        assert_eq!(
            (r.n_fail, r.max_error, r.pixels, r.npels),
            (0, 0.0, 48, 12),
            "{s:?}"
        );
    }
    // Against the full frame: the pixels outside fail, reported where they are; the
    // percentages are of the reference's data window (idiff's npels)
    let f = read_image(&d.join("full.exr")).unwrap();
    let r = compare(&c, &f, &Thresholds::default()).unwrap();
    assert_eq!((r.n_fail, r.max_at, r.npels), (48 - 12 - 1, (7, 5, 0), 12));
    // A difference inside the crop is reported at its place in the frame, not in the crop
    let mut moved = crop.clone();
    moved[5] += 0.5; // (1, 1) of the crop: (3, 3) of the frame
    write(
        &d.join("crop2.exr"),
        (4, 3),
        (2, 2),
        frame(8, 6),
        &[("Y", moved)],
    );
    let (code, out, _) = diff(&d, &["crop.exr", "crop2.exr"]);
    assert_eq!(code, 2, "{out}");
    assert!(out.contains("@ (3, 3, Y)"), "{out}");
    // The same pixels one column further: misaligned, they fail
    write(
        &d.join("shifted.exr"),
        (4, 3),
        (3, 2),
        frame(8, 6),
        &[("Y", crop)],
    );
    let (code, out, _) = diff(&d, &["crop.exr", "shifted.exr"]);
    assert_eq!(code, 2, "{out}");
    // Another display window: a different frame, refused (exit 3); idiff compares
    write(
        &d.join("wide.exr"),
        (8, 6),
        (0, 0),
        ((0, 0), (10, 6)),
        &[("Y", full)],
    );
    let (code, _, err) = diff(&d, &["full.exr", "wide.exr"]);
    assert_eq!(code, 3, "{err}");
    assert!(err.contains("in display window 10x6+0+0"), "{err}");
    assert_eq!(diff(&d, &["full.exr", "wide.exr", "--idiff-compat"]).0, 0);
}

//! `rayproof diff REF TEST`: image comparison with OpenImageIO `idiff`'s semantics, plus relMSE,
//! HDR-ꟻLIP and an optional noise-aware per-pixel z-test.
//!
//! ```text
//! rayproof diff REF TEST [--layer NAME]
//!                        [--fail F --failrelative R --failpercent P --hardfail H --allowfailures N]
//!                        [--warn F --warnrelative R --warnpercent P --hardwarn H]
//!                        [--diff-exr FILE] [--heatmap FILE.png] [--json FILE|-] [--no-flip] [-q]
//!                        [--variance REF_VAR.exr [--spp N] [--significance A] [--pixel-success-rate S]]
//!                        [--idiff-compat]
//! ```
//!
//! The command line of `rayproof diff` and its output files are in `cli/diff.rs`; this module does
//! not depend on it. Its exit codes follow idiff (0 PASS, 1 WARNING, 2 FAILURE, 3 display window,
//! channels or layer differ, 4 an unreadable input; in full in the [crate documentation](crate)).
//!
//! It prints what OpenImageIO's `idiff` prints: mean error, RMS, PSNR; the max error @ (x, y,
//! channel) with both values; the pixels over warn and over fail. It adds relMSE and mean
//! HDR-ꟻLIP (NVIDIA's exposure range and ACES tone mapper over the `nv-flip` crate, keeping the
//! per-pixel maximum over exposures).
//!
//! The metrics and the verdict follow `idiff` (OIIO `idiff.cpp`, `imagebufalgo_compare.cpp`):
//! a pixel fails if any channel has |a−b| > `fail` and |a−b|/mean(|a|,|b|) > `failrelative`;
//! the verdict is PASS if nfail ≤ `allowfailures`, else FAILURE if nfail > `failpercent`% of
//! the pixels or the max error > `hardfail`, else WARNING if nwarn > `warnpercent`% or the max
//! error > `hardwarn`, else PASS.
//!
//! The arithmetic is idiff 2.4's: differences and thresholds in float32 (`--fail 0.05` is
//! 0.05000000075), sums in double over batches of 4,096 pixels, PNG code values × (1/255) in
//! float32 as OpenImageIO converts them.
//!
//! **Parity with the real idiff, live.** `tests/idiff_live.rs` runs OpenImageIO's own `idiff`
//! (2.4.7, Debian's `openimageio-tools`; the test fails when it is missing) on the 21 pairs of
//! `scripts/idiff-pairs` (noise offsets, relative changes, HDR, negative and tiny values, a
//! threshold edge, NaN and Inf pixels, RGB against RGBA, different sizes, 8-bit PNGs) under 10
//! option sets, and on pairs it makes with the real `oiiotool` under 4 of them: float, half,
//! RGBA, tiled, every compression (and the lossy ones against their source), Blender-style
//! multilayer, single-channel `R`, `Y`, `Z`, 8- and 16-bit PNG (RGB, grey, alpha, `sRGB` and
//! `gAMA` chunks, an `oFFs` offset), moved, cropped and overscanned data windows, display windows
//! away from (0, 0), a multipart file, a truncated file. With `--idiff-compat`, `rayproof diff`
//! matches every exit code, both pixel counts and their percentages, and mean, RMS, PSNR and max
//! error (value, place and channel) as idiff prints them, but on the truncated file, which
//! idiff reads as zeros and rayproof refuses; without it, it matches the same way on every pair
//! except those of the README's table of deliberate differences (checked row by row at idiff's
//! defaults), where it is deliberately stricter for CI or compares one layer; on the multilayer
//! pairs it matches idiff on the files reduced to the layer it reports. (Until then,
//! `tests/idiff.rs` checked 210 runs recorded from idiff; the live test replaced them: every
//! pair can be run by the real tool.)
//!
//! **EXR files as renderers write them** ([`read_image_layer`]): a multilayer file (Blender's
//! `ViewLayer.Combined.R/G/B/A`, `ViewLayer.Depth.Z`, or the parts of a multipart file) is read
//! one layer at a time: `--layer NAME`, by default a `Combined` layer, else the first with `R`,
//! `G`, `B`, else the only one (several and none of these is refused, listing them); the report
//! and the JSON say which ([`LayerInfo`]). `--idiff-compat` without `--layer` reads every channel
//! of the first part, as idiff. Channels come in OpenImageIO's order (`R`, `G`, `B`, `A`, then
//! the others), so positions of the maximum and its channel are idiff's. A single channel (`R`,
//! `Y`, `Z`) or a grey PNG is one channel. Pixel positions are absolute, in the coordinates of
//! the data and display windows (a data window at (8, 12) shifts them, as in idiff); two images
//! are compared over the union of their data windows, a pixel outside an image's data window
//! being 0 ([`align`]); the percentages (and `failpercent`) are of the reference's data window,
//! as idiff's. At most [`MAX_CHANNELS`] channels are read from a file.
//!
//! Deliberate differences from `idiff` ([`Semantics::Rayproof`]; `--idiff-compat` selects
//! [`Semantics::Idiff`], which reproduces idiff on all of them but the truncated file):
//! - images of different display windows, channels or layers are refused (exit 3), not compared
//!   over the union of their data windows with missing values read as 0 (data windows that
//!   differ within one display window are compared over their union, as idiff does);
//! - every NaN/Inf mismatch is a failing (and warning) pixel, left out of the mean, RMS and
//!   relMSE sums (whose denominators stay pixels × channels); idiff counts none of the NaN ones
//!   nor the first Inf, and its sums turn inf or nan; +Inf against −Inf is a mismatch (idiff:
//!   equal); NaN = NaN and Inf = Inf of the same sign stay equal;
//! - one layer of a multilayer EXR is compared (see above), where idiff compares all channels;
//! - a PNG's colour is compared as stored (straight alpha), where OpenImageIO multiplies it by
//!   alpha when reading (hiding colour changes under low alpha);
//! - a truncated or corrupt file is refused (exit 4), even with `--idiff-compat`: idiff reads
//!   what it can and the rest as 0, and can pass it;
//! - the report is always printed in full, and a NaN/Inf mismatch line says how it was counted;
//!   its `Max error` line shows the one channel's two values, with enough digits to reproduce
//!   them; it says which layer was read and, when it is not the display window at (0, 0), the
//!   compared window;
//! - `--diff-exr` writes |REF − TEST| whenever asked, even for identical images;
//! - PNGs are kept display-referred (not linearised);
//! - additions: relMSE, mean ꟻLIP, the z-test, `--json`, `--heatmap`.
//!
//! Additions:
//! - relMSE = mean over pixels × channels of d² / (ref² + 0.01);
//! - mean ꟻLIP ([`flip_error`]): HDR-ꟻLIP for scene-linear input, LDR-ꟻLIP when both images
//!   are PNGs; both go through nv-flip's 8-bit input, so differences under one sRGB code value
//!   can vanish. A PNG compared with an EXR is compared as stored, with a note;
//! - `--variance VAR.exr [--spp N]`: Mitsuba's z-test ([`z_test`]); the variance is the
//!   per-sample variance when N > 1, the variance of the test pixel itself when N = 1 (the
//!   default). z = |img − ref|·sqrt(spp / max(var, 1e-4)), with a Šidák-corrected
//!   α = 1 − (1 − 0.01)^(1/pixels), passing when ≥ 99.75 % of channel tests pass (the defaults of
//!   `--significance` and `--pixel-success-rate`). The verdict is then the z-test's, PASS or FAILURE.
//!   A variance sample that is NaN, infinite or negative is refused with one line (exit 4 in
//!   `diff`, the test refused in `check`): an infinite variance would pass any difference;
//! - `--heatmap`: magma map of the ꟻLIP error, or with `--no-flip` of the largest channel
//!   |d| × 16 clamped to 1 (like Blender's `idiff … --mulc 16`);
//! - `--json FILE`: the comparison, thresholds and z-test; `--json -` prints the JSON on
//!   stdout instead of the text report. JSON has no infinity: `"inf"` stands for it.
//!
//! One file per job: `io` (the [`Image`] type, readers and writers, the 8-bit preview),
//! `metrics` (idiff's metrics, thresholds and verdict), `flip` (HDR-ꟻLIP), `ztest` (the
//! noise-aware z-test) and `report` (the text and JSON reports); their public items are
//! re-exported here.

pub mod diff;
mod flip;
mod io;
mod maps;
mod mask;
mod metrics;
mod report;
mod ztest;

pub use flip::{flip_error, hdr_flip, heatmap_rgb8, ldr_flip, FlipKind};
pub(crate) use io::check_declared;
pub use io::{
    decode_bounded, exr_planes_to, exr_to, png_rgb8_to, read_image, read_image_layer, srgb8,
    tonemap_rgb8, write_exr_rgb, write_png_rgb8, Image, ImageError, LayerInfo, LayerPick,
    LayerSelect, Window, MAX_ANCILLARY_BYTES, MAX_CHANNELS, MAX_IMAGE_BYTES, MAX_PIXELS,
};
pub use io::{escape_controls, one_line};
pub use maps::{diff_map, diff_map_rgb8, fail_mask, mask_rgb8, DiffMap};
pub use mask::{mask_overlay_rgb8, Mask, MaskCounts, MaskPart};
pub use metrics::{
    abs_diff, abs_error_map, align, compare, compare_as, compare_masked, verdict, AlignError,
    Comparison, Semantics, SizeMismatch, Thresholds, Verdict,
};
pub use report::{fmt_g, report_text, DiffReport};
pub use ztest::{erfc, sidak_alpha, z_test, z_test_masked, ZParams, ZTest, ZTestError};

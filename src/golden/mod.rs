//! `rayproof check`: golden-image CI for any renderer. A suite file ([`suite`]) lists tests;
//! each test's image is read, made by the user's renderer command, or rendered by rayproof, and
//! compared with its references under idiff's thresholds plus rayproof's (`max_mean`,
//! `max_flip`, the z-test when a variance image is given). rayproof's own reference scenes are
//! one such suite, `reference/suite.toml`: their POV-Ray and Mitsuba renders are external
//! references, `NAME/rayproof.exr` the golden.
//!
//! - A reference with a `manifest.json` entry beside it must match its SHA-256 (else REFUSED:
//!   tampered). An external reference whose entry records another version of the test's scene
//!   (or of a declared input) is REFUSED as stale: rayproof cannot re-make it. The test's own
//!   golden made from another version of its scene or inputs is **stale, not refused**: the
//!   test renders and is compared as usual, its row warns `stale golden` (and the row's `stale`
//!   field says which files), and `--update` re-blesses it. Its width, height and sampling grid
//!   are the ones the test image is made with, unless the test says otherwise (then a warning).
//! - The renderer's output is checked before it is compared: a regular file (not a directory or
//!   a symbolic link), not empty, of the declared `output` format, decodable, at most 256 EXR
//!   layers, the size its `{width}`/`{height}` asked for; else REFUSED with one line
//!   ([`formats`]). The bytes compared are the bytes `--update` blesses.
//! - A renderer that fails is reported by the lines of its standard error that explain it (those
//!   that say error, fatal or cannot, and the last few; POV-Ray's `cannot open the user
//!   configuration file` and option listing are left out: [`crate::process::explain`]). With
//!   `--report DIR` each test's whole log (the command as run, how it ended, its standard error
//!   and output) is kept as `DIR/logs/TEST.log`: the row's `log` field, linked from the HTML
//!   and the JUnit XML.
//! - A missing required reference, a renderer command that fails, hangs past the suite's
//!   timeout or writes no readable image: REFUSED, one line in the row. A missing optional
//!   reference: SKIPPED.
//! - `--update` writes a golden (a copy of the test image, with a manifest entry: SHA-256, the
//!   command as the suite writes it, never a scratch path; the test's own scene as written and
//!   its inputs by SHA-256; width, height, grid; the date) where the golden comparison fails,
//!   the golden is missing or it is stale (every stale golden, passing or not, so that after
//!   `--update` no golden is stale), never an external reference, and nothing at all when any
//!   test of the run was refused.
//!
//! One file per job: `suite` (the suite file), `references` (rules, manifests, hashes, bless),
//! `rows` (the results and their tables), `html` and `junit` (the reports); this file runs it.
//!
//! ```text
//! rayproof check [--suite FILE] [--report DIR] [--update] [--json FILE] [--junit FILE]
//!                [--markdown FILE] [--method M,..] [--precision f32,f64] [--test NAME,..] [--flip]
//! ```
//!
//! # Your own suite
//!
//! The suite file's format is in [`suite`]; the README has a complete suite that runs from the
//! repository's root with a stand-in renderer (`tests/suite.rs` runs it as printed).
//! - **Thresholds** layer: the suite's `[thresholds]`, then the test's `thresholds = {…}`, then the
//!   reference's own. Keys: idiff's (`fail`, `failrelative`, `failpercent`, `hardfail`,
//!   `allowfailures`, `warn`, `warnrelative`, `warnpercent`, `hardwarn`), `max_mean`, `max_flip`
//!   (mean HDR-ꟻLIP), `known_failure`; with `variance = "{variance}"` (your renderer writes the
//!   per-pixel variance there) or a path, Mitsuba's z-test decides, with `significance` and
//!   `pixel_success_rate` (see [`crate::images`]). A `known_failure` entry marks a comparison that
//!   is expected to fail (XFAIL); if it starts to pass, `check` fails (XPASS).
//! - **Sampling grid.** A reference's manifest entry (as `scripts/render-references`, `rayproof
//!   reference` ([`renderers`]) and `--update` write: SHA-256, commands, width, grid, date) gives
//!   the test its `{width}` and `{grid}` (`{spp}` = grid²), so a correct render is made with the
//!   reference's grid and cannot fail on a sampling mismatch.
//! - **Warnings** in every report: a linear EXR against an sRGB-encoded PNG (compared as stored),
//!   mismatched sampling grids, NaN/Inf pixels in either image.
//! - **Outputs**: the terminal table (failures first, refusals first of all), `--report DIR` (the
//!   HTML page, in the style of Blender's render report: failures first; tone-mapped new and
//!   reference images that swap on hover, the failing pixels, the |difference| normalised to
//!   its maximum (a 1e-6 change shows) with the maximum ringed, and an HDR-ꟻLIP heat map; the
//!   metrics beside them; [`html()`]), `--json`, `--markdown`, `--junit` (JUnit XML valid against
//!   `junit-10.xsd`: failures, XPASS and NEW as `<failure>`, refusals as `<error>`, XFAIL and
//!   skipped optional references as `<skipped>`, times that add up; the table in [`junit()`]).
//! - **Exit codes** of `check`: 0 every comparison passes (warnings, XFAIL and SKIPPED included);
//!   1 a comparison fails (FAILURE, XPASS, a missing golden; a stale golden counts as its
//!   comparison does); 2 the suite file does not validate or bad usage (one line, nothing runs);
//!   3 a test was refused: its renderer command failed, hung past `timeout` or wrote no usable
//!   image, or a required reference is missing, tampered, stale or unreadable. A refused test is one line in its row of every report, and then `--update`
//!   writes nothing at all, no golden and no manifest.
//!
//! In CI (GitHub Actions, after installing rayproof and your renderer):
//!
//! ```yaml
//! - name: Golden images
//!   run: rayproof check --suite tests/render-suite.toml --junit junit.xml --report check-report
//! - uses: actions/upload-artifact@v4
//!   if: always()
//!   with: { name: check-report, path: check-report }
//! - uses: mikepenz/action-junit-report@v4
//!   if: always()
//!   with: { report_paths: junit.xml }
//! ```
//!
//! # rayproof's own references
//!
//! rayproof's renders are checked against reference images from the real **POV-Ray 3.7** (Debian)
//! and **Mitsuba 3** (PyPI), rendered from the same scene files (exported as
//! [`crate::render::export`] describes). The references, their manifests and the thresholds are
//! committed under `reference/` (see `reference/README.md`).
//!
//! `rayproof check` without `--suite` runs `reference/suite.toml`: it renders every scene of
//! `reference/scenes/` with the gated configuration (`promote` f64) at the references' size and
//! grid (256 wide, 8×8), and compares the render with:
//! - `povray.exr` and `mitsuba.exr`, under the per-scene thresholds: fail above 0.05 for more than
//!   0.1 % of pixels, and a mean error of at most 1e-3;
//! - `rayproof.exr`, rayproof's own previous render, to 1e-6.
//!
//! A reference whose SHA-256 does not match its manifest is refused, and so is one made from
//! another version of the scene file. `--update` rewrites only failing or missing `rayproof.exr`
//! goldens, never the POV-Ray or Mitsuba files. CI runs `check` after the tests; here it took 90 s
//! for the 24 comparisons (2 cores; `fan30` at 1024² is most of it).
//!
//! **Scripts** (they install nothing silently):
//! - `scripts/render-povray SCENE`: says how to get `povray` if it is missing.
//! - `scripts/render-mitsuba SCENE`: makes a venv with `mitsuba` and `numpy` in
//!   `~/.cache/rayproof`, fetches libLLVM 19 with `apt-get download` for the llvm variant, and
//!   falls back to `scalar_rgb`.
//! - `scripts/render-references [NAME..]`: runs both renderers for every scene. It writes
//!   `reference/NAME/{povray,mitsuba}.exr` and the manifest entries: renderer, version, exact
//!   commands, grid, date, seconds, the file's SHA-256 and the scene file's SHA-256.
//! - `scripts/verify-references [NAME]`: re-renders one scene (default `glass`) with both real
//!   renderers and diffs the result against the committed files. It is not part of CI. Last run:
//!   both bit-identical (mean error 0).
//! - `scripts/check-table`: produces the table below.
//!
//! # What the references show
//!
//! - POV-Ray and rayproof `promote`/f64 agree to a mean error of about 1e-6 on every scene. Mitsuba
//!   agrees to about 1e-5: Mitsuba traces in float32.
//! - Mitsuba's `llvm_ad_rgb` variant intersects spheres in float32. On `floor` (a sphere of radius
//!   1e6) about half the floor is self-shadowed (MAE 0.08). The `floor` reference therefore uses
//!   `scalar_rgb`, which intersects spheres in float64.
//! - At the image level, Fan et al.'s methods fail in **f64 as well as f32**. `algebraic` and
//!   `geometric` in f64 speckle the spheres: 1.3–4 % of pixels are off by more than 0.05, against
//!   0.1–0.3 % in f32. The cause is the ray offset, not the primary hits. With `offset = 1e-6`
//!   both match POV-Ray to a mean error of 1.3e-6 (measured). With the automatic offset,
//!   16 ulps × max(1, |p|), a shadow or reflection ray starts so close to the sphere that these
//!   methods' error in the small root exceeds the offset, and the ray re-hits the sphere it
//!   leaves. In f32 the same rule gives a distance 2^29 times larger, which hides the error.
//! - `rtg7` f64 passes every scene except `floor`: 16.8 % of pixels fail against POV-Ray. Its
//!   primary hits are exact (`rayproof probe` shows 0 ulps for a camera ray to the floor). But a
//!   ray leaving the floor forms o − c with |c| = 1e6, which f64 resolves only to 1.2e-10, so the
//!   offset of about 1e-14 is too small. With `offset = 1e-9` it matches POV-Ray (mean error
//!   1.1e-6). Only `promote`, which forms o − c exactly, passes everywhere with the automatic
//!   offset. A size-aware offset rule (pbrt-style error bounds) was left for the reintersection
//!   work of issue 6, which made it [`crate::audit::robustness::offset`]; the renderer's `auto` offset is
//!   still the 16-ulp rule.
//!
//! # The comparison table
//!
//! From `scripts/check-table` (one `rayproof check --json --markdown` run): 102 comparisons, 6
//! scenes × 2 references × 8 method/precision pairs, plus the goldens. FAILURE rows are expected
//! outside the gated `promote f64`.
//!
//! | scene | reference | method / precision | status | MAE | RMS | PSNR dB | max error | pixels > fail | HDR-FLIP |
//! |---|---|---|---|---|---|---|---|---|---|
//! | diffuse | mitsuba | algebraic f32 | FAILURE | 4.41e-4 | 2.83e-3 | 50.9 | 0.086 | 0.127 % | 0.0095 |
//! | diffuse | mitsuba | algebraic f64 | FAILURE | 1.16e-3 | 6.46e-3 | 43.8 | 0.144 | 1.334 % | 0.0208 |
//! | diffuse | mitsuba | geometric f32 | FAILURE | 5.74e-4 | 3.46e-3 | 49.2 | 0.093 | 0.206 % | 0.0119 |
//! | diffuse | mitsuba | geometric f64 | FAILURE | 1.83e-3 | 9.73e-3 | 40.2 | 0.179 | 3.543 % | 0.0307 |
//! | diffuse | mitsuba | promote f32 | PASS | 9.19e-7 | 4.85e-5 | 86.3 | 0.004 | 0.000 % | 0.0001 |
//! | diffuse | mitsuba | promote f64 | PASS | 9.19e-7 | 4.85e-5 | 86.3 | 0.004 | 0.000 % | 0.0001 |
//! | diffuse | mitsuba | rtg7 f32 | PASS | 9.20e-7 | 4.85e-5 | 86.3 | 0.004 | 0.000 % | 0.0001 |
//! | diffuse | mitsuba | rtg7 f64 | PASS | 9.19e-7 | 4.85e-5 | 86.3 | 0.004 | 0.000 % | 0.0001 |
//! | diffuse | povray | algebraic f32 | FAILURE | 4.41e-4 | 2.83e-3 | 51.0 | 0.086 | 0.127 % | 0.0094 |
//! | diffuse | povray | algebraic f64 | FAILURE | 1.16e-3 | 6.46e-3 | 43.8 | 0.144 | 1.332 % | 0.0206 |
//! | diffuse | povray | geometric f32 | FAILURE | 5.75e-4 | 3.46e-3 | 49.2 | 0.093 | 0.206 % | 0.0118 |
//! | diffuse | povray | geometric f64 | FAILURE | 1.83e-3 | 9.73e-3 | 40.2 | 0.179 | 3.545 % | 0.0306 |
//! | diffuse | povray | promote f32 | PASS | 1.26e-6 | 2.75e-6 | 111.2 | 0.000 | 0.000 % | 0.0001 |
//! | diffuse | povray | promote f64 | PASS | 1.26e-6 | 2.75e-6 | 111.2 | 0.000 | 0.000 % | 0.0001 |
//! | diffuse | povray | rtg7 f32 | PASS | 1.26e-6 | 2.75e-6 | 111.2 | 0.000 | 0.000 % | 0.0001 |
//! | diffuse | povray | rtg7 f64 | PASS | 1.26e-6 | 2.75e-6 | 111.2 | 0.000 | 0.000 % | 0.0001 |
//! | diffuse | rayproof | promote f64 | PASS | 0.00e0 | 0.00e0 | inf | 0.000 | 0.000 % | 0.0000 |
//! | fan30 | mitsuba | algebraic f32 | FAILURE | 1.44e-3 | 7.44e-3 | 42.6 | 0.151 | 1.131 % | 0.0387 |
//! | fan30 | mitsuba | algebraic f64 | FAILURE | 2.43e-3 | 1.21e-2 | 38.3 | 0.246 | 2.002 % | 0.0563 |
//! | fan30 | mitsuba | geometric f32 | FAILURE | 1.88e-3 | 9.28e-3 | 40.6 | 0.175 | 1.608 % | 0.0491 |
//! | fan30 | mitsuba | geometric f64 | FAILURE | 3.01e-3 | 1.31e-2 | 37.7 | 0.230 | 2.780 % | 0.0694 |
//! | fan30 | mitsuba | promote f32 | PASS | 7.20e-6 | 9.12e-5 | 80.8 | 0.007 | 0.000 % | 0.0015 |
//! | fan30 | mitsuba | promote f64 | PASS | 7.31e-6 | 9.22e-5 | 80.7 | 0.007 | 0.000 % | 0.0015 |
//! | fan30 | mitsuba | rtg7 f32 | PASS | 7.19e-6 | 9.11e-5 | 80.8 | 0.007 | 0.000 % | 0.0015 |
//! | fan30 | mitsuba | rtg7 f64 | PASS | 7.31e-6 | 9.22e-5 | 80.7 | 0.007 | 0.000 % | 0.0015 |
//! | fan30 | povray | algebraic f32 | FAILURE | 1.43e-3 | 7.43e-3 | 42.6 | 0.151 | 1.129 % | 0.0384 |
//! | fan30 | povray | algebraic f64 | FAILURE | 2.43e-3 | 1.21e-2 | 38.3 | 0.246 | 2.000 % | 0.0561 |
//! | fan30 | povray | geometric f32 | FAILURE | 1.88e-3 | 9.28e-3 | 40.6 | 0.176 | 1.610 % | 0.0488 |
//! | fan30 | povray | geometric f64 | FAILURE | 3.01e-3 | 1.31e-2 | 37.7 | 0.230 | 2.782 % | 0.0691 |
//! | fan30 | povray | promote f32 | PASS | 1.33e-6 | 1.20e-5 | 98.4 | 0.001 | 0.000 % | 0.0005 |
//! | fan30 | povray | promote f64 | PASS | 1.15e-6 | 3.08e-6 | 110.2 | 0.000 | 0.000 % | 0.0004 |
//! | fan30 | povray | rtg7 f32 | PASS | 1.33e-6 | 1.16e-5 | 98.7 | 0.001 | 0.000 % | 0.0005 |
//! | fan30 | povray | rtg7 f64 | PASS | 1.15e-6 | 3.08e-6 | 110.2 | 0.000 | 0.000 % | 0.0004 |
//! | fan30 | rayproof | promote f64 | PASS | 0.00e0 | 0.00e0 | inf | 0.000 | 0.000 % | 0.0000 |
//! | far | mitsuba | algebraic f32 | FAILURE | 1.52e-2 | 5.01e-2 | 26.0 | 0.706 | 15.411 % | 0.3794 |
//! | far | mitsuba | algebraic f64 | FAILURE | 4.28e-3 | 1.51e-2 | 36.4 | 0.168 | 6.891 % | 0.1278 |
//! | far | mitsuba | geometric f32 | FAILURE | 1.90e-2 | 5.56e-2 | 25.1 | 0.598 | 18.979 % | 0.4192 |
//! | far | mitsuba | geometric f64 | FAILURE | 4.67e-3 | 1.68e-2 | 35.5 | 0.182 | 7.150 % | 0.1380 |
//! | far | mitsuba | promote f32 | PASS | 6.28e-7 | 2.20e-6 | 113.2 | 0.000 | 0.000 % | 0.0011 |
//! | far | mitsuba | promote f64 | PASS | 5.51e-8 | 2.53e-7 | 131.9 | 0.000 | 0.000 % | 0.0005 |
//! | far | mitsuba | rtg7 f32 | PASS | 1.22e-6 | 5.94e-6 | 104.5 | 0.000 | 0.000 % | 0.0014 |
//! | far | mitsuba | rtg7 f64 | PASS | 5.51e-8 | 2.53e-7 | 131.9 | 0.000 | 0.000 % | 0.0005 |
//! | far | povray | algebraic f32 | FAILURE | 1.52e-2 | 5.01e-2 | 26.0 | 0.706 | 15.411 % | 0.3794 |
//! | far | povray | algebraic f64 | FAILURE | 4.28e-3 | 1.51e-2 | 36.4 | 0.168 | 6.891 % | 0.1278 |
//! | far | povray | geometric f32 | FAILURE | 1.90e-2 | 5.56e-2 | 25.1 | 0.598 | 18.979 % | 0.4192 |
//! | far | povray | geometric f64 | FAILURE | 4.67e-3 | 1.68e-2 | 35.5 | 0.181 | 7.150 % | 0.1380 |
//! | far | povray | promote f32 | PASS | 6.57e-7 | 2.35e-6 | 112.6 | 0.000 | 0.000 % | 0.0012 |
//! | far | povray | promote f64 | PASS | 1.87e-7 | 9.35e-7 | 120.6 | 0.000 | 0.000 % | 0.0006 |
//! | far | povray | rtg7 f32 | PASS | 1.25e-6 | 6.00e-6 | 104.4 | 0.000 | 0.000 % | 0.0016 |
//! | far | povray | rtg7 f64 | PASS | 1.87e-7 | 9.35e-7 | 120.6 | 0.000 | 0.000 % | 0.0006 |
//! | far | rayproof | promote f64 | PASS | 0.00e0 | 0.00e0 | inf | 0.000 | 0.000 % | 0.0000 |
//! | floor | mitsuba | algebraic f32 | FAILURE | 1.39e-3 | 6.03e-3 | 44.4 | 0.133 | 0.897 % | 0.0283 |
//! | floor | mitsuba | algebraic f64 | FAILURE | 1.80e-2 | 2.64e-2 | 31.6 | 0.121 | 7.336 % | 0.1354 |
//! | floor | mitsuba | geometric f32 | FAILURE | 1.63e-3 | 7.16e-3 | 42.9 | 0.133 | 1.632 % | 0.0321 |
//! | floor | mitsuba | geometric f64 | FAILURE | 1.86e-2 | 2.75e-2 | 31.2 | 0.156 | 8.651 % | 0.1427 |
//! | floor | mitsuba | promote f32 | PASS | 1.48e-4 | 1.52e-3 | 56.4 | 0.037 | 0.000 % | 0.0021 |
//! | floor | mitsuba | promote f64 | PASS | 1.48e-4 | 1.52e-3 | 56.4 | 0.037 | 0.000 % | 0.0021 |
//! | floor | mitsuba | rtg7 f32 | FAILURE | 7.32e-4 | 3.94e-3 | 48.1 | 0.106 | 0.144 % | 0.0153 |
//! | floor | mitsuba | rtg7 f64 | FAILURE | 2.19e-2 | 3.32e-2 | 29.6 | 0.150 | 16.522 % | 0.1346 |
//! | floor | povray | algebraic f32 | FAILURE | 1.46e-3 | 6.48e-3 | 43.8 | 0.140 | 0.966 % | 0.0290 |
//! | floor | povray | algebraic f64 | FAILURE | 1.82e-2 | 2.66e-2 | 31.5 | 0.121 | 7.674 % | 0.1360 |
//! | floor | povray | geometric f32 | FAILURE | 1.71e-3 | 7.59e-3 | 42.4 | 0.140 | 1.713 % | 0.0328 |
//! | floor | povray | geometric f64 | FAILURE | 1.88e-2 | 2.78e-2 | 31.1 | 0.156 | 9.017 % | 0.1432 |
//! | floor | povray | promote f32 | PASS | 1.15e-6 | 2.40e-6 | 112.4 | 0.000 | 0.000 % | 0.0001 |
//! | floor | povray | promote f64 | PASS | 1.15e-6 | 2.40e-6 | 112.4 | 0.000 | 0.000 % | 0.0001 |
//! | floor | povray | rtg7 f32 | FAILURE | 7.11e-4 | 4.38e-3 | 47.2 | 0.119 | 0.218 % | 0.0155 |
//! | floor | povray | rtg7 f64 | FAILURE | 2.20e-2 | 3.33e-2 | 29.5 | 0.150 | 16.793 % | 0.1351 |
//! | floor | rayproof | promote f64 | PASS | 0.00e0 | 0.00e0 | inf | 0.000 | 0.000 % | 0.0000 |
//! | glass | mitsuba | algebraic f32 | FAILURE | 3.90e-4 | 2.71e-3 | 51.4 | 0.086 | 0.127 % | 0.0087 |
//! | glass | mitsuba | algebraic f64 | FAILURE | 1.01e-3 | 6.15e-3 | 44.2 | 0.144 | 1.266 % | 0.0179 |
//! | glass | mitsuba | geometric f32 | FAILURE | 6.41e-4 | 3.61e-3 | 48.9 | 0.094 | 0.256 % | 0.0193 |
//! | glass | mitsuba | geometric f64 | FAILURE | 2.01e-3 | 9.99e-3 | 40.0 | 0.179 | 3.586 % | 0.0452 |
//! | glass | mitsuba | promote f32 | PASS | 1.28e-5 | 1.67e-4 | 75.5 | 0.008 | 0.000 % | 0.0015 |
//! | glass | mitsuba | promote f64 | PASS | 1.29e-5 | 1.68e-4 | 75.5 | 0.008 | 0.000 % | 0.0015 |
//! | glass | mitsuba | rtg7 f32 | PASS | 1.28e-5 | 1.67e-4 | 75.5 | 0.008 | 0.000 % | 0.0015 |
//! | glass | mitsuba | rtg7 f64 | PASS | 1.29e-5 | 1.68e-4 | 75.5 | 0.008 | 0.000 % | 0.0015 |
//! | glass | povray | algebraic f32 | FAILURE | 3.79e-4 | 2.70e-3 | 51.4 | 0.086 | 0.127 % | 0.0076 |
//! | glass | povray | algebraic f64 | FAILURE | 1.00e-3 | 6.15e-3 | 44.2 | 0.144 | 1.265 % | 0.0167 |
//! | glass | povray | geometric f32 | FAILURE | 6.36e-4 | 3.61e-3 | 48.9 | 0.094 | 0.258 % | 0.0191 |
//! | glass | povray | geometric f64 | FAILURE | 2.01e-3 | 9.99e-3 | 40.0 | 0.179 | 3.586 % | 0.0449 |
//! | glass | povray | promote f32 | PASS | 1.44e-6 | 2.09e-5 | 93.6 | 0.003 | 0.000 % | 0.0003 |
//! | glass | povray | promote f64 | PASS | 1.32e-6 | 1.82e-5 | 94.8 | 0.003 | 0.000 % | 0.0002 |
//! | glass | povray | rtg7 f32 | PASS | 1.45e-6 | 2.14e-5 | 93.4 | 0.003 | 0.000 % | 0.0003 |
//! | glass | povray | rtg7 f64 | PASS | 1.32e-6 | 1.82e-5 | 94.8 | 0.003 | 0.000 % | 0.0002 |
//! | glass | rayproof | promote f64 | PASS | 0.00e0 | 0.00e0 | inf | 0.000 | 0.000 % | 0.0000 |
//! | mirror | mitsuba | algebraic f32 | FAILURE | 8.03e-4 | 4.24e-3 | 47.5 | 0.086 | 0.143 % | 0.0137 |
//! | mirror | mitsuba | algebraic f64 | FAILURE | 1.67e-3 | 7.79e-3 | 42.2 | 0.144 | 1.447 % | 0.0264 |
//! | mirror | mitsuba | geometric f32 | FAILURE | 1.02e-3 | 5.20e-3 | 45.7 | 0.103 | 0.302 % | 0.0176 |
//! | mirror | mitsuba | geometric f64 | FAILURE | 2.53e-3 | 1.14e-2 | 38.9 | 0.179 | 4.109 % | 0.0386 |
//! | mirror | mitsuba | promote f32 | PASS | 1.34e-6 | 5.67e-5 | 84.9 | 0.004 | 0.000 % | 0.0002 |
//! | mirror | mitsuba | promote f64 | PASS | 1.34e-6 | 5.67e-5 | 84.9 | 0.004 | 0.000 % | 0.0002 |
//! | mirror | mitsuba | rtg7 f32 | PASS | 1.34e-6 | 5.67e-5 | 84.9 | 0.004 | 0.000 % | 0.0002 |
//! | mirror | mitsuba | rtg7 f64 | PASS | 1.34e-6 | 5.67e-5 | 84.9 | 0.004 | 0.000 % | 0.0002 |
//! | mirror | povray | algebraic f32 | FAILURE | 8.03e-4 | 4.24e-3 | 47.5 | 0.086 | 0.143 % | 0.0136 |
//! | mirror | povray | algebraic f64 | FAILURE | 1.67e-3 | 7.79e-3 | 42.2 | 0.144 | 1.445 % | 0.0263 |
//! | mirror | povray | geometric f32 | FAILURE | 1.02e-3 | 5.19e-3 | 45.7 | 0.103 | 0.302 % | 0.0174 |
//! | mirror | povray | geometric f64 | FAILURE | 2.53e-3 | 1.14e-2 | 38.9 | 0.179 | 4.111 % | 0.0385 |
//! | mirror | povray | promote f32 | PASS | 1.28e-6 | 2.79e-6 | 111.1 | 0.000 | 0.000 % | 0.0001 |
//! | mirror | povray | promote f64 | PASS | 1.28e-6 | 2.79e-6 | 111.1 | 0.000 | 0.000 % | 0.0001 |
//! | mirror | povray | rtg7 f32 | PASS | 1.28e-6 | 2.79e-6 | 111.1 | 0.000 | 0.000 % | 0.0001 |
//! | mirror | povray | rtg7 f64 | PASS | 1.28e-6 | 2.79e-6 | 111.1 | 0.000 | 0.000 % | 0.0001 |
//! | mirror | rayproof | promote f64 | PASS | 0.00e0 | 0.00e0 | inf | 0.000 | 0.000 % | 0.0000 |

pub mod calibrate;
pub mod ci;
pub mod formats;
mod html;
mod junit;
mod references;
pub mod renderers;
mod rows;
pub mod suite;

pub use html::html;
pub use junit::junit;
pub use references::{sha256_bytes, sha256_file, utc_now, Config, Provenance, Rule};
pub use rows::{counts, log_tail, markdown, table, ReportImages, Row, Status, LOG_TAIL_LINES};
pub use suite::{Source, Suite, Test};

use crate::images::{self, Comparison, Image, Verdict, ZParams};
use crate::render::{self, scene};
use anyhow::{bail, Result};
use references::{bless, verified_reference, Blessing, Sources};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What `check` was asked to do.
pub struct Options {
    /// Write the report's images to this directory (the staging directory of `--report`).
    pub report: Option<PathBuf>,
    /// `--update`: write the goldens that fail or are missing (only if no test is refused).
    pub update: bool,
    /// Extra configurations for the tests rayproof renders (compared with their external
    /// references only).
    pub configs: Vec<Config>,
    /// Only these tests (by name); empty: all.
    pub tests: Vec<String>,
    /// Compute ꟻLIP for every comparison (LDR when both images are PNG, else HDR), even without
    /// `report` or a `max_flip` rule.
    pub flip: bool,
    /// The value of `{seed}` in renderer commands (`--seed`, default 0; `--calibrate` renders
    /// with seeds 1 to N).
    pub seed: u64,
}

/// The rows of a run and what `--update` did.
pub struct Outcome {
    /// Failures first.
    pub rows: Vec<Row>,
    /// Goldens written by `--update`.
    pub blessed: Vec<PathBuf>,
    /// `--update` was asked for but some test was refused, so nothing was written.
    pub update_withheld: bool,
}

impl Outcome {
    /// Rows whose reference or test image could not be used.
    pub fn refused(&self) -> usize {
        self.rows
            .iter()
            .filter(|r| r.status == Status::Refused)
            .count()
    }
    /// Rows that fail (failures, unexpected passes, refusals, missing goldens).
    pub fn failed(&self) -> usize {
        self.rows.iter().filter(|r| r.status.is_failure()).count()
    }
    /// 0 every comparison passes (warnings, known failures and skipped optional references
    /// included), 1 some comparison fails, 3 some test was refused.
    pub fn exit_code(&self) -> u8 {
        if self.refused() > 0 {
            3
        } else if self.failed() > 0 {
            1
        } else {
            0
        }
    }
}

/// The test image, however it was made.
struct Made {
    image: Image,
    /// The bytes it was decoded from (what `--update` blesses: the image compared) and their
    /// format.
    bytes: Vec<u8>,
    format: formats::Format,
    variance: Option<Image>,
    /// How it was made, for a golden's manifest entry: the command as the suite writes it.
    command: String,
    renderer: String,
}

/// The frame a test image is made with, and where it came from.
#[derive(Clone, Copy, Default)]
struct Frame {
    width: Option<u32>,
    height: Option<u32>,
    grid: Option<u32>,
}

/// At most this much of a renderer's standard output goes into its log (the first and last
/// halves).
const LOG_STDOUT_KEEP: usize = 128 << 10;

/// The log of one renderer run: the command as run, how it ended, its standard error and
/// output.
fn renderer_log(
    command: &str,
    dir: &Path,
    ran: &Result<crate::process::Finished, String>,
    stderr: &str,
) -> String {
    let mut log = format!("$ {command}\n# in {}\n", dir.display());
    match ran {
        Ok(f) => log += &format!("# {}\n", f.status),
        Err(e) => log += &format!("# {e}\n"),
    }
    log += "--- standard error ---\n";
    log += stderr;
    if !log.ends_with('\n') {
        log.push('\n');
    }
    if let Ok(f) = ran {
        log += "--- standard output ---\n";
        let out = &f.stdout;
        if out.len() > LOG_STDOUT_KEEP {
            let half = LOG_STDOUT_KEEP / 2;
            log += &String::from_utf8_lossy(&out[..half]);
            log += &format!(
                "\n[… {} bytes of standard output left out …]\n",
                out.len() - 2 * half
            );
            log += &String::from_utf8_lossy(&out[out.len() - half..]);
        } else {
            log += &String::from_utf8_lossy(out);
        }
    }
    log
}

/// Makes the test image: reads it, runs the renderer command, or renders the scene. Also
/// returns the renderer's whole log and the tail of its standard error (a command's only),
/// however the run ended.
fn make(
    suite: &Suite,
    t: &Test,
    frame: Frame,
    scratch: &Path,
    seed: u64,
) -> (Result<Made, String>, Option<String>, Option<String>) {
    let (mut log, mut tail) = (None, None);
    let made = make_logged(suite, t, (frame, seed), scratch, &mut log, &mut tail);
    (made, log, tail)
}

fn make_logged(
    suite: &Suite,
    t: &Test,
    (frame, seed): (Frame, u64),
    scratch: &Path,
    log: &mut Option<String>,
    tail: &mut Option<String>,
) -> Result<Made, String> {
    let out = scratch.join(format!("{}.{}", t.name, t.out_ext));
    let var = scratch.join(format!("{}.variance.exr", t.name));
    let abs = |p: &Path| std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf());
    let (file, command, renderer) = match &t.source {
        suite::Source::Image(p) => {
            // The user's own file: a link to it is followed
            (abs(p), format!("(image {})", p.display()), String::new())
        }
        suite::Source::Rayproof(cfg) => {
            // Render in process at the frame's size and grid, written as the golden would be
            let scene_path = t.scene.as_ref().expect("validated: rayproof needs a scene");
            let sc = scene::load(scene_path).map_err(|e| format!("{e:#}"))?;
            let fr = render::scene::Frame::of(&sc, frame.width, frame.grid)?;
            let ov = render::Overrides {
                method: Some(cfg.method),
                precision: Some(cfg.precision),
                grid: Some(fr.grid),
                size: Some((fr.width, fr.height)),
                force_all_effects: false,
                progress: false,
                beauty_only: true,
                ..Default::default()
            };
            let r = render::render(&sc, &ov);
            let img = Image::rgb(
                r.width,
                r.height,
                r.beauty.iter().flatten().copied().collect(),
            );
            images::write_exr_rgb(&out, &img).map_err(|e| format!("{e:#}"))?;
            let command = format!(
                "rayproof render {} --method {} --precision {} --width {} --spp {} -o OUT.exr",
                scene_path.display(),
                cfg.method.name,
                cfg.precision,
                fr.width,
                fr.grid * fr.grid
            );
            (
                out.clone(),
                command,
                format!("rayproof {}", env!("CARGO_PKG_VERSION")),
            )
        }
        suite::Source::Command(template) => {
            // Fill the placeholders; the ones the frame cannot give are an error
            let keys = suite::placeholders(template)?;
            let need = |k: &str, v: Option<u32>| -> Result<String, String> {
                v.map(|x| x.to_string()).ok_or_else(|| {
                    let what = match k {
                        "width" | "height" => k,
                        _ => "grid",
                    };
                    format!("the command uses {{{k}}} but neither the test nor a reference's manifest gives a {what}")
                })
            };
            let mut values = vec![
                ("out", out.display().to_string()),
                ("variance", var.display().to_string()),
                ("name", t.name.clone()),
                ("seed", seed.to_string()),
            ];
            if let Some(p) = &suite.platform {
                values.push(("platform", p.clone()));
            }
            if let Some(s) = &t.scene {
                values.push(("scene", abs(s).display().to_string()));
            }
            for k in &keys {
                match k.as_str() {
                    "width" => values.push(("width", need("width", frame.width)?)),
                    "height" => values.push(("height", need("height", frame.height)?)),
                    "grid" => values.push(("grid", need("grid", frame.grid)?)),
                    "spp" => values.push(("spp", need("spp", frame.grid.map(|g| g * g))?)),
                    _ => {}
                }
            }
            let filled = suite::fill(template, &values);
            // Run it under control, its whole log kept
            let (ran, stderr) = crate::process::run_logged(
                "renderer",
                &filled,
                Some(&suite.dir),
                b"",
                suite.timeout,
                crate::process::STDOUT_CAP,
            );
            *log = Some(renderer_log(&filled, &suite.dir, &ran, &stderr));
            let failed = match &ran {
                Ok(f) => crate::process::failure("renderer", f).is_some(),
                Err(_) => true,
            };
            *tail = rows::log_tail(&stderr, failed);
            let f = ran?;
            if let Some(e) = crate::process::failure("renderer", &f) {
                return Err(e);
            }
            if std::fs::symlink_metadata(&out).is_err() {
                return Err(format!(
                    "renderer exited 0 but wrote no image at {}{} ('{filled}')",
                    out.display(),
                    elsewhere(scratch, &t.name, &out)
                ));
            }
            // The frame it was asked for is the frame it must make
            let image_check = |img: &Image| -> Result<(), String> {
                for (k, want, have) in [
                    ("width", frame.width, img.width),
                    ("height", frame.height, img.height),
                ] {
                    if let Some(w) = want.filter(|_| keys.iter().any(|x| x == k)) {
                        if w as usize != have {
                            return Err(format!(
                                "the renderer wrote a {}×{} image, but its command was given {{{k}}} = {w}",
                                img.width, img.height
                            ));
                        }
                    }
                }
                Ok(())
            };
            let ti = formats::read_test_image(&out, t.output)?;
            image_check(&ti.image)?;
            return Ok(Made {
                image: ti.image,
                bytes: ti.bytes,
                format: ti.format,
                variance: variance(suite, t, &var)?,
                command: t.command.clone().unwrap_or_default(),
                renderer: String::new(),
            });
        }
    };
    // Read the image, and its variance if the test gives one
    let ti = formats::read_test_image(&file, t.output)?;
    Ok(Made {
        image: ti.image,
        bytes: ti.bytes,
        format: ti.format,
        variance: variance(suite, t, &var)?,
        command,
        renderer,
    })
}

/// The test's variance image, if it gives one.
fn variance(suite: &Suite, t: &Test, var: &Path) -> Result<Option<Image>, String> {
    match &t.variance {
        None => Ok(None),
        Some(v) => {
            let p = match v.as_str() {
                "{variance}" => var.to_path_buf(),
                v => suite.dir.join(v.replace("{name}", &t.name)),
            };
            Ok(Some(
                formats::read_any(&p).map_err(|e| format!("the variance image: {e}"))?,
            ))
        }
    }
}

/// When a renderer wrote no file at `out`: what it wrote beside it under the test's name, as a
/// hint (`; it wrote a.png instead: set output = "png"`), or nothing.
fn elsewhere(scratch: &Path, name: &str, out: &Path) -> String {
    let mut found: Vec<String> = std::fs::read_dir(scratch)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|f| f.starts_with(&format!("{name}.")) && !f.contains(".variance."))
        .filter(|f| Some(f.as_str()) != out.file_name().and_then(|n| n.to_str()))
        .collect();
    found.sort();
    match found.first() {
        None => String::new(),
        Some(f) => match Path::new(f)
            .extension()
            .and_then(|e| e.to_str())
            .filter(|e| formats::Format::from_ext(e).is_some())
        {
            Some(ext) => format!("; it wrote {f} instead: set output = \"{ext}\" in the suite"),
            None => format!("; it wrote {f} instead"),
        },
    }
}

/// Judges one comparison under its rule; the z-test's verdict replaces idiff's when given. A
/// test image with NaN or Inf pixels (`nonfinite`: how many with each) fails whatever the
/// thresholds, unless the test allows them.
fn judge(
    c: &Comparison,
    z: Option<&images::ZTest>,
    rule: &Rule,
    nonfinite: Option<(usize, usize)>,
) -> (Status, String) {
    let mut why = vec![];
    let allowed = nonfinite.is_none();
    // Never a pass, not even as an expected failure: a known failure is about differences
    let nonfinite = nonfinite.filter(|(nan, inf)| nan + inf > 0).map(|(nan, inf)| {
        format!(
            "the test image has {nan} NaN and {inf} Inf pixel(s): never a pass (allow_nonfinite = true in the test allows them)"
        )
    });
    // A test that allows NaN/Inf has them judged as failing pixels under its percentages (the
    // comparison's own verdict fails any NaN/Inf mismatch)
    let verdict = z.map(|z| z.verdict).unwrap_or(if allowed {
        images::verdict(c.n_fail, c.n_warn, c.max_error, c.pixels, &rule.idiff)
    } else {
        c.verdict
    });
    if verdict == Verdict::Failure {
        why.push(match z {
            Some(z) if z.beyond_noise > 0 => format!(
                "z-test: {} pixels beyond any noise (NaN/Inf, a channel the variance lacks, or a change where the calibration's renders never varied)",
                z.beyond_noise
            ),
            Some(z) if z.shift_p <= z.shift_alpha => {
                let (k, zk) = z
                    .shift_z
                    .iter()
                    .enumerate()
                    .fold((0, 0f64), |b, (k, v)| if v.abs() > b.1.abs() { (k, *v) } else { b });
                format!(
                    "z-test: the image's mean shifted beyond its noise (channel {}: {zk:+.1} σ of the mean, p = {:.1e} ≤ {:.1e}); {} pixels fail alone",
                    z.channels.get(k).map_or("?", |c| c.as_str()),
                    z.shift_p,
                    z.shift_alpha,
                    z.failing_pixels
                )
            }
            Some(z) => format!(
                "z-test: {} pixels fail at α = {:.2e}",
                z.failing_pixels, z.alpha
            ),
            None => format!(
                "{} px ({:.3} %) over fail {}",
                c.n_fail,
                100.0 * c.n_fail as f64 / c.pixels.max(1) as f64,
                rule.idiff.fail
            ),
        });
    }
    if c.mean_error > rule.max_mean {
        why.push(format!(
            "mean error {:.3e} > max_mean {:.0e}",
            c.mean_error, rule.max_mean
        ));
    }
    if let (Some(max), Some(f)) = (rule.max_flip, c.flip_mean) {
        if f > max {
            why.push(format!("mean ꟻLIP {f:.4} > max_flip {max}"));
        }
    }
    if let Some(n) = nonfinite {
        why.insert(0, n);
        return (Status::Failure, why.join("; "));
    }
    let failed = !why.is_empty();
    // Which test decided a pass: the z-test, said so (the idiff columns then do not judge)
    if let (false, Some(z)) = (failed, z) {
        let worst = z.shift_z.iter().fold(0f64, |m, v| m.max(v.abs()));
        why.push(format!(
            "z-test{}: {} of {} pixels within noise, mean shift ≤ {worst:.1} σ",
            match z.params.dof {
                0 => String::new(),
                k => format!(" (calibrated, {} renders)", k + 1),
            },
            z.pixels - z.failing_pixels,
            z.pixels
        ));
    }
    let note = why.join("; ");
    match (&rule.known_failure, failed) {
        (Some(k), true) => (Status::KnownFailure, k.clone()),
        (Some(k), false) => (
            Status::UnexpectedPass,
            format!("listed as a known failure ({k}) but passes: remove the entry"),
        ),
        (None, true) => (Status::Failure, note),
        (None, false) if verdict == Verdict::Warning => (Status::Warning, note),
        (None, false) => (Status::Pass, note),
    }
}

/// Pixels with a NaN or an infinity in some channel.
fn nonfinite_pixels(img: &Image) -> usize {
    let (nan, inf) = nan_inf_pixels(img);
    nan + inf
}

/// Pixels with a NaN in some channel, and pixels with an infinity (and no NaN).
fn nan_inf_pixels(img: &Image) -> (usize, usize) {
    let pixels = img.data.chunks(img.channels.len().max(1));
    pixels.fold((0, 0), |(nan, inf), p| {
        if p.iter().any(|v| v.is_nan()) {
            (nan + 1, inf)
        } else if p.iter().any(|v| v.is_infinite()) {
            (nan, inf + 1)
        } else {
            (nan, inf)
        }
    })
}

/// The warnings of one comparison: encodings, sampling grids, NaN/Inf.
fn warnings(
    reference: &Image,
    prov: &Provenance,
    made: &Made,
    frame_grid: Option<u32>,
) -> Vec<String> {
    let mut w = vec![];
    let enc = |d: bool| {
        if d {
            "sRGB-encoded (PNG)"
        } else {
            "scene-linear"
        }
    };
    if reference.display_referred != made.image.display_referred {
        w.push(format!(
            "the reference is {} and the test image {}: compared as stored, not converted",
            enc(reference.display_referred),
            enc(made.image.display_referred)
        ));
    }
    if let (Some(want), Some(have)) = (prov.grid, frame_grid) {
        if want != have {
            w.push(format!(
                "sampling grid: the reference was made with {want}×{want} per pixel, the test image with {have}×{have}"
            ));
        }
    }
    for (what, img) in [("reference", reference), ("test image", &made.image)] {
        let n = nonfinite_pixels(img);
        if n > 0 {
            w.push(format!("the {what} has {n} pixels with NaN or Inf"));
        }
    }
    w
}

/// A row with nothing compared yet.
fn row(t: &Test, reference: &str, status: Status, note: String) -> Row {
    Row {
        test: t.name.clone(),
        reference: reference.into(),
        renderer: String::new(),
        config: t.config(),
        status,
        note,
        warnings: vec![],
        comparison: None,
        ztest: None,
        rule: t
            .references
            .iter()
            .find(|r| r.name == reference)
            .map(|r| r.rule.clone())
            .or(t.golden.as_ref().map(|g| g.1.clone()))
            .unwrap_or_else(|| Rule::from_layers(&[]).expect("defaults parse")),
        render_seconds: 0.0,
        seconds: 0.0,
        replay: String::new(),
        log_tail: None,
        images: None,
        stale: None,
        log: None,
        platform: None,
        mask: None,
    }
}

/// A row for each of the test's comparisons (its references, then its golden), all with one
/// status and note: a test skipped, or refused before anything was made.
fn every_row(t: &Test, status: Status, why: &str) -> Vec<Row> {
    let names = t.references.iter().map(|r| r.name.as_str());
    let golden = t.golden.as_ref().map(|_| "golden");
    names
        .chain(golden)
        .map(|n| row(t, n, status, why.to_string()))
        .collect()
}

/// What `--update` may bless of a test: its image, the frame and the sources it was made from.
type ToBless = (Made, Frame, Sources);

/// A test's rows, and its image when `--update` may bless it.
type TestRun = (Vec<Row>, Option<ToBless>);

/// The test's scene and declared inputs, hashed (one line naming the file that cannot be read).
fn sources(t: &Test) -> Result<Sources, String> {
    let hash = |what: &str, p: &Path| sha256_file(p).map_err(|e| format!("the {what}: {e:#}"));
    let scene = match (&t.scene, &t.scene_name) {
        (Some(p), Some(n)) => Some((n.clone(), hash("scene", p)?)),
        _ => None,
    };
    let mut inputs = vec![];
    for (n, p) in &t.inputs {
        inputs.push((n.clone(), hash(&format!("input {n}"), p)?));
    }
    let command = match &t.source {
        Source::Command(_) => t.command.clone(),
        _ => None,
    };
    let frame = [("width", t.width), ("height", t.height), ("grid", t.grid)];
    Ok(Sources {
        scene,
        inputs,
        command,
        frame,
    })
}

/// Keeps a test's renderer log in the report (`logs/NAME.log`); its path relative to the report
/// directory, for the rows.
fn keep_log(o: &Options, t: &Test, log: Option<String>) -> Result<Option<String>> {
    let (Some(dir), Some(log)) = (&o.report, log) else {
        return Ok(None);
    };
    let name = format!("logs/{}.log", t.name);
    std::fs::create_dir_all(dir.join("logs"))?;
    std::fs::write(dir.join(&name), log.as_bytes())?;
    Ok(Some(name))
}

/// One test: its references checked, its image made, every comparison judged. Also returns
/// the image (for `--update`) when the golden comparison failed, the golden is missing or it is
/// stale (made from another version of the scene or inputs: always re-blessed).
///
/// Times it as [`Row::seconds`] says: each row its own comparison, the first row that is not
/// a skipped optional reference (else the first) also the rest of the test's wall time
/// (references, render), so the render is counted once.
fn run_test(suite: &Suite, t: &Test, o: &Options, scratch: &Path) -> Result<TestRun> {
    let start = Instant::now();
    let (mut rows, made) = judge_test(suite, t, o, scratch)?;
    let compared: f64 = rows.iter().map(|r| r.seconds).sum();
    let first = rows.iter().position(|r| r.status != Status::Skipped);
    if let Some(r) = first.or((!rows.is_empty()).then_some(0)) {
        rows[r].seconds += (start.elapsed().as_secs_f64() - compared).max(0.0);
    }
    Ok((rows, made))
}

/// [`run_test`] without the test's own time: rows carry their comparison's time only.
fn judge_test(suite: &Suite, t: &Test, o: &Options, scratch: &Path) -> Result<TestRun> {
    let mut rows = vec![];
    // Skipped on this platform: a row per comparison, saying why, nothing made
    if let Some(why) = &t.skip {
        let why = format!(
            "skipped on platform {}: {why}",
            suite.platform.as_deref().unwrap_or_default()
        );
        return Ok((every_row(t, Status::Skipped, &why), None));
    }
    // The scene's and inputs' hashes, for stale references
    let now = match sources(t) {
        Ok(s) => s,
        Err(why) => return Ok((every_row(t, Status::Refused, &why), None)),
    };
    // The mask's parts, its images read once
    let mask_parts = match mask_parts(t) {
        Ok(p) => p,
        Err(why) => {
            let why = format!("the mask: {why}");
            return Ok((every_row(t, Status::Refused, &why), None));
        }
    };
    // Load every reference (the golden last); missing, tampered, corrupt and stale external
    // references are refused; a stale golden is compared and re-blessed
    let mut loaded = vec![];
    let golden = t.golden.as_ref().map(|(p, rule)| ("golden", p, true, rule));
    let refs = t
        .references
        .iter()
        .map(|r| (r.name.as_str(), &r.path, r.required, &r.rule));
    let mut golden_missing = false;
    let mut golden_stale = None;
    for (name, path, required, rule) in refs.chain(golden) {
        if !path.exists() {
            if name == "golden" {
                golden_missing = true;
                rows.push(row(
                    t,
                    name,
                    Status::New,
                    format!("no golden at {}: run with --update", path.display()),
                ));
            } else if required {
                rows.push(row(
                    t,
                    name,
                    Status::Refused,
                    format!("required reference missing: {}", path.display()),
                ));
            } else {
                rows.push(row(
                    t,
                    name,
                    Status::Skipped,
                    format!("optional reference missing: {}", path.display()),
                ));
            }
            continue;
        }
        let own = name == "golden";
        match verified_reference(path, &now, own) {
            Ok((_, _, Some(what))) if !own => rows.push(row(
                t,
                name,
                Status::Refused,
                format!(
                    "{} was made from another version of {what}: re-render it",
                    path.display()
                ),
            )),
            Ok((img, prov, stale)) => {
                if own {
                    golden_stale = stale;
                }
                loaded.push((name, rule, img, prov))
            }
            Err(e) => rows.push(row(t, name, Status::Refused, format!("{e:#}"))),
        }
    }
    if loaded.is_empty() && !golden_missing {
        // A test that compares nothing proves nothing: not a pass
        if rows.iter().all(|r| r.status == Status::Skipped) {
            rows.push(row(
                t,
                "-",
                Status::Refused,
                "nothing to compare with: every reference is optional and missing, and the test has no golden".into(),
            ));
        }
        return Ok((rows, None));
    }
    // The frame: the test's, else the references' manifests' (which must agree)
    let mut frame = Frame {
        width: t.width,
        height: t.height,
        grid: t.grid,
    };
    for what in ["width", "height", "grid"] {
        let get = |p: &Provenance| match what {
            "width" => p.width,
            "height" => p.height,
            _ => p.grid,
        };
        let said: Vec<(&str, u32)> = loaded
            .iter()
            .filter_map(|(n, _, _, p)| get(p).map(|v| (*n, v)))
            .collect();
        let slot = match what {
            "width" => &mut frame.width,
            "height" => &mut frame.height,
            _ => &mut frame.grid,
        };
        if slot.is_none() {
            if said.iter().any(|(_, v)| *v != said[0].1) {
                let list: Vec<String> = said.iter().map(|(n, v)| format!("{n} {v}")).collect();
                let why = format!("the references' manifests disagree on the {what} ({}): give {what} in the test", list.join(", "));
                rows.extend(
                    loaded
                        .iter()
                        .map(|(n, ..)| row(t, n, Status::Refused, why.clone())),
                );
                return Ok((rows, None));
            }
            *slot = said.first().map(|s| s.1);
        }
    }
    // Make the test image once; its renderer's log is kept in the report
    let rendering = Instant::now();
    let (made, log, tail) = make(suite, t, frame, scratch, o.seed);
    let render_seconds = rendering.elapsed().as_secs_f64();
    let log = keep_log(o, t, log)?;
    for r in rows.iter_mut() {
        (r.render_seconds, r.log_tail) = (render_seconds, tail.clone());
    }
    let made = match made {
        Ok(m) => m,
        Err(e) => {
            let why = format!("test image: {e}");
            rows.extend(loaded.iter().map(|(n, ..)| Row {
                render_seconds,
                log_tail: tail.clone(),
                ..row(t, n, Status::Refused, why.clone())
            }));
            if golden_missing {
                for r in rows.iter_mut().filter(|r| r.reference == "golden") {
                    (r.status, r.note) = (Status::Refused, why.clone());
                }
            }
            for r in rows.iter_mut() {
                r.log = log.clone();
            }
            return Ok((rows, None));
        }
    };
    // A golden keeps its real format: one whose name says another is never written
    let golden_format = t
        .golden
        .as_ref()
        .map(|(g, _)| (g, formats::Format::of_path(g)));
    if let Some((g, f)) = golden_format.filter(|(_, f)| *f != Some(made.format)) {
        let why = format!(
            "the test image is a {} file but the golden {} names {}: name it .{} (a golden keeps its real format)",
            made.format.name(),
            g.display(),
            f.map_or("no format rayproof reads".into(), |f| f.name()),
            made.format.extensions()[0]
        );
        loaded.retain(|(n, ..)| *n != "golden");
        rows.retain(|r| r.reference != "golden");
        rows.push(row(t, "golden", Status::Refused, why));
        golden_missing = false;
        golden_stale = None;
    }
    // Compare with each reference and judge
    let frame_grid = match &t.source {
        suite::Source::Rayproof(_) | suite::Source::Command(_) => frame.grid,
        suite::Source::Image(_) => t.grid,
    };
    let mut golden_failed = golden_missing;
    for (name, rule, reference, prov) in &loaded {
        let comparing = Instant::now();
        let mut r = row(t, name, Status::Refused, String::new());
        (r.rule, r.renderer, r.render_seconds, r.log_tail) = (
            (*rule).clone(),
            prov.renderer.clone(),
            render_seconds,
            tail.clone(),
        );
        r.warnings = warnings(reference, prov, &made, frame_grid);
        if *name == "golden" {
            if let Some(what) = &golden_stale {
                r.warnings.insert(
                    0,
                    format!(
                        "stale golden: made from another version of {what}; --update re-blesses it"
                    ),
                );
                r.stale = Some(what.clone());
            }
        }
        // A multilayer file: which layer was compared, in every output (the text's warning
        // lines, the JSON's comparison, the JUnit body, the HTML row)
        let labels: Vec<String> = [&made.image.layer, &reference.layer]
            .into_iter()
            .map(|l| l.as_ref().map(|l| l.label()).unwrap_or_default())
            .collect();
        if labels.iter().any(|l| !l.is_empty()) {
            r.warnings.push(if labels[0] == labels[1] {
                format!("layer read: {}", labels[0])
            } else {
                format!(
                    "layer read: {} of the test image, {} of the reference",
                    if labels[0].is_empty() {
                        "its only layer"
                    } else {
                        &labels[0]
                    },
                    if labels[1].is_empty() {
                        "its only layer"
                    } else {
                        &labels[1]
                    }
                )
            });
        }
        // The mask over this frame (a rectangle outside it, a mask image of another size: refused)
        let mask = match mask_parts.is_empty() {
            true => None,
            false => match images::Mask::build(reference.display, &mask_parts) {
                Ok(m) => Some(m),
                Err(e) => {
                    (r.status, r.note) = (Status::Refused, format!("the mask: {e}"));
                    rows.push(r);
                    continue;
                }
            },
        };
        let compared = match &mask {
            Some(m) => images::compare_masked(reference, &made.image, &rule.idiff, m),
            None => images::compare(reference, &made.image, &rule.idiff),
        };
        // A mask that leaves nothing to compare proves nothing
        let compared = compared.map(|c| (c.pixels == 0, c));
        if let Ok((true, _)) = compared {
            (r.status, r.note) = (
                Status::Refused,
                "the mask leaves no pixel to compare: nothing was compared".into(),
            );
            rows.push(r);
            continue;
        }
        match compared.map(|(_, c)| c) {
            Err(e) => {
                (r.status, r.note) = (Status::Failure, format!("{e}"));
            }
            Ok(mut c) => {
                // Both over the union of their data windows (one display window: compare
                // refused anything else), for the z-test, ꟻLIP and the previews
                let (reference, image) = match images::align(reference, &made.image) {
                    Ok(pair) => pair,
                    Err(e) => {
                        (r.status, r.note) = (Status::Refused, format!("{e}"));
                        rows.push(r);
                        continue;
                    }
                };
                let reference = &reference;
                // The z-test, when a variance is given: a calibrated golden's own (Student's t
                // over its renders), else the renderer's
                let calibrated = match (&prov.calibration, *name == "golden") {
                    (Some((renders, path, sha)), true) => {
                        // The variance the calibration wrote, by its own record too (another
                        // test's --update could re-enter it in the manifest)
                        let same = sha256_file(path).ok().as_ref() == Some(sha);
                        let read = verified_reference(path, &Sources::default(), false)
                            .and_then(|v| match same {
                                true => Ok(v),
                                false => anyhow::bail!(
                                    "{} is not the variance its calibration wrote (SHA-256 {sha}): re-calibrate",
                                    path.display()
                                ),
                            });
                        match read {
                            Ok((v, ..)) => Some((v, 1, u64::from(*renders) - 1)),
                            Err(e) => {
                                (r.status, r.note) = (
                                    Status::Refused,
                                    format!("the calibrated golden's variance: {e:#}"),
                                );
                                rows.push(r);
                                continue;
                            }
                        }
                    }
                    _ => None,
                };
                let variance =
                    calibrated.or_else(|| made.variance.clone().map(|v| (v, t.variance_spp, 0)));
                let z = match &variance {
                    Some((v, spp, dof)) => {
                        let p = ZParams {
                            spp: *spp,
                            significance: rule.significance,
                            pixel_success_rate: rule.pixel_success_rate,
                            shift_significance: rule.shift_significance,
                            dof: *dof,
                        };
                        // over the same window (0 outside its data window)
                        let v = match v.display == reference.display {
                            true => v.padded(reference.data_window()),
                            false => v.clone(),
                        };
                        match images::z_test_masked(reference, &image, &v, &p, mask.as_ref()) {
                            Ok(z) => Some(z),
                            Err(e) => {
                                (r.status, r.note) =
                                    (Status::Refused, format!("the variance image: {e}"));
                                r.seconds = comparing.elapsed().as_secs_f64();
                                rows.push(r);
                                continue;
                            }
                        }
                    }
                    None => None,
                };
                // ꟻLIP, when a rule or the report needs it
                let map = if o.flip || o.report.is_some() || rule.max_flip.is_some() {
                    let (kind, mean, map) = images::flip_error(reference, &image);
                    // Under a mask: each pixel's ꟻLIP times its weight, over the pixels compared
                    let mean = mask
                        .as_ref()
                        .map_or(mean, |m| m.weighted_mean(image.data_window(), &map));
                    (c.flip_mean, c.flip_kind) = (Some(mean), Some(kind));
                    Some(map)
                } else {
                    None
                };
                let nonfinite = (!t.allow_nonfinite).then(|| nan_inf_pixels(&made.image));
                (r.status, r.note) = judge(&c, z.as_ref(), rule, nonfinite);
                if let Some(m) = &mask {
                    let counts = m.counts(c.window);
                    r.warnings.push(format!(
                        "mask: {} pixel(s) left out, {} judged with scaled tolerances",
                        counts.excluded, counts.scaled
                    ));
                    r.mask = Some(counts);
                }
                if let (Some(dir), Some(map)) = (&o.report, map) {
                    let view = Compared {
                        reference,
                        image: &image,
                        flip: &map,
                        mask: mask.as_ref(),
                        z: z.as_ref(),
                    };
                    r.images = Some(write_images(dir, &r, &view, rule)?);
                }
                r.comparison = Some(c);
                r.ztest = z;
            }
        }
        if *name == "golden" && matches!(r.status, Status::Failure | Status::New) {
            golden_failed = true;
        }
        r.seconds = comparing.elapsed().as_secs_f64();
        rows.push(r);
    }
    for r in rows.iter_mut() {
        r.log = log.clone();
    }
    let mut bless = golden_failed || golden_stale.is_some();
    // A calibrated golden (the mean of N renders) is re-made by --calibrate, never replaced by
    // one render
    let calibrated = loaded
        .iter()
        .any(|(n, _, _, p)| *n == "golden" && p.calibration.is_some());
    if bless && calibrated && o.update {
        bless = false;
        for r in rows.iter_mut().filter(|r| r.reference == "golden") {
            r.warnings.push(
                "a calibrated golden: --update does not replace the mean of its renders with one render; re-make it with --calibrate N".into(),
            );
        }
    }
    Ok((rows, bless.then_some((made, frame, now))))
}

/// The command that runs one test again: `rayproof check --suite SUITE --test NAME`, with the
/// method and precision of an extra configuration (`extra`); paths and names quoted for `sh`
/// when they need it.
fn replay_command(suite: &Suite, t: &Test, extra: bool, seed: u64) -> String {
    let q = |s: &str| {
        let plain = !s.is_empty()
            && s.chars()
                .all(|c| c.is_ascii_alphanumeric() || "-_./,:+=@%".contains(c));
        if plain {
            s.to_string()
        } else {
            format!("'{}'", s.replace('\'', r"'\''"))
        }
    };
    let mut c = format!(
        "rayproof check --suite {} --test {}",
        q(&suite.path.display().to_string()),
        q(&t.name)
    );
    if let Some(p) = &suite.platform {
        c += &format!(" --platform {}", q(p));
    }
    if seed != 0 {
        c += &format!(" --seed {seed}");
    }
    if let (true, Source::Rayproof(cfg)) = (extra, &t.source) {
        c += &format!(
            " --method {} --precision {}",
            cfg.method.name, cfg.precision
        );
    }
    c
}

/// Runs a suite; `--update` stages goldens into `outputs` (committed with the run's other
/// outputs) only after every test ran and none was refused.
pub fn run(suite: &Suite, o: &Options, outputs: &mut crate::output::Outputs) -> Result<Outcome> {
    // Select the tests; every name asked for must exist
    for n in &o.tests {
        if !suite.tests.iter().any(|t| &t.name == n) {
            let known: Vec<&str> = suite.tests.iter().map(|t| t.name.as_str()).collect();
            bail!(
                "no test '{n}' in {} (known: {})",
                suite.path.display(),
                known.join(", ")
            );
        }
    }
    let mut tests: Vec<Test> = suite
        .tests
        .iter()
        .filter(|t| o.tests.is_empty() || o.tests.contains(&t.name))
        .cloned()
        .collect();
    // Extra configurations of the tests rayproof renders: external references only
    let extra: Vec<Test> = tests
        .iter()
        .filter_map(|t| match &t.source {
            Source::Rayproof(c) => Some((t, c.label())),
            _ => None,
        })
        .flat_map(|(t, label)| {
            o.configs
                .iter()
                .filter(move |c| c.label() != label)
                .map(move |c| Test {
                    source: Source::Rayproof(*c),
                    golden: None,
                    ..t.clone()
                })
        })
        .filter(|t| !t.references.is_empty())
        .collect();
    let own = tests.len();
    tests.extend(extra);
    // Run every test
    let scratch = crate::output::ScratchDir::new("check")?;
    let mut rows = vec![];
    let mut to_bless = vec![];
    for (i, t) in tests.iter().enumerate() {
        let (mut r, made) = run_test(suite, t, o, &scratch.0)?;
        let replay = replay_command(suite, t, i >= own, o.seed);
        for row in &mut r {
            row.replay = replay.clone();
            row.platform = suite.platform.clone();
        }
        rows.extend(r);
        if let (Some(m), Some((golden, _))) = (made, &t.golden) {
            to_bless.push((t, golden.clone(), m));
        }
    }
    // Bless: only when nothing was refused; failing, missing and stale goldens
    let refused = rows.iter().any(|r| r.status == Status::Refused);
    let mut blessed = vec![];
    let mut records = references::Records::default();
    if o.update && !refused {
        for (t, golden, (m, frame, sources)) in to_bless {
            // Never bless an image with NaN or Inf
            let bad = nonfinite_pixels(&m.image);
            if bad > 0 {
                for r in rows.iter_mut().filter(|r| {
                    r.test == t.name && r.reference == "golden" && r.config == t.config()
                }) {
                    r.note =
                        format!("not blessed: the test image has {bad} pixels with NaN or Inf");
                    r.status = Status::Failure;
                }
                continue;
            }
            let b = Blessing {
                renderer: if m.renderer.is_empty() {
                    suite.name.clone()
                } else {
                    m.renderer.clone()
                },
                command: m.command.clone(),
                width: frame.width.or(Some(m.image.width as u32)),
                height: frame.height.or(Some(m.image.height as u32)),
                grid: frame.grid,
                sources,
                calibration: None,
            };
            bless(&mut records, &golden, m.bytes, &b)?;
            for r in rows
                .iter_mut()
                .filter(|r| r.test == t.name && r.reference == "golden" && r.config == t.config())
            {
                let was = match r.stale {
                    Some(_) if r.status == Status::Pass => "stale".to_string(),
                    Some(_) => format!("{}, stale", r.status.label()),
                    None => r.status.label().to_string(),
                };
                r.note = format!("{was} → written: {}", golden.display());
                r.status = Status::Updated;
            }
            blessed.push(golden);
        }
    }
    // The goldens and their manifests, staged with the run's other outputs
    records.stage(outputs)?;
    // Failures first (refusals first of all), then warnings, then by test
    rows.sort_by_key(|r| {
        (
            r.status != Status::Refused,
            !r.status.is_failure(),
            r.status != Status::Warning && r.warnings.is_empty(),
            r.test.clone(),
        )
    });
    Ok(Outcome {
        rows,
        blessed,
        update_withheld: o.update && refused,
    })
}

/// One comparison's images over one window, for the report's PNGs.
struct Compared<'a> {
    reference: &'a Image,
    image: &'a Image,
    flip: &'a [f32],
    mask: Option<&'a images::Mask>,
    z: Option<&'a images::ZTest>,
}

/// A test's mask, its images read (a mask image is a file the suite reads; one line if it
/// cannot be read).
fn mask_parts(t: &Test) -> Result<Vec<images::MaskPart>, String> {
    let mut parts = vec![];
    for m in &t.mask {
        parts.push(match m {
            suite::MaskSource::Rect([x, y, w, h], weight) => images::MaskPart::Rect {
                x: *x,
                y: *y,
                width: *w as u64,
                height: *h as u64,
                weight: *weight,
            },
            suite::MaskSource::Image(p) => images::MaskPart::Image(formats::read_any(p)?),
        });
    }
    Ok(parts)
}

/// The report's PNGs of one comparison: the new render and the reference tone-mapped, the
/// failing-pixel mask, the normalised |difference| map and the ꟻLIP heat map.
fn write_images(dir: &Path, row: &Row, view: &Compared, rule: &Rule) -> Result<ReportImages> {
    let (reference, img, flip) = (view.reference, view.image, view.flip);
    let config = row.config.replace(' ', "-");
    let pair = format!("{}-{}-{config}", row.test, row.reference);
    let (w, h) = (img.width, img.height);
    let new_rgb = images::tonemap_rgb8(img);
    // The failing pixels: the z-test's when it decides, else those over `fail`
    let mask = match view.z {
        Some(z) => z.failing_map.clone(),
        None => images::fail_mask(reference, img, &rule.idiff, view.mask)?,
    };
    let diff = images::diff_map(reference, img, view.mask)?;
    // ꟻLIP under the mask as the comparison weighs it
    let flip: Vec<f32> = match view.mask {
        Some(m) => flip
            .iter()
            .zip(m.over(img.data_window()))
            .map(|(f, w)| f * w)
            .collect(),
        None => flip.to_vec(),
    };
    let out = ReportImages {
        new: format!("{}-new-{config}.png", row.test),
        reference: format!("{}-{}.png", row.test, row.reference),
        mask: format!("{pair}-mask.png"),
        diff: format!("{pair}-diff.png"),
        flip: format!("{pair}-flip.png"),
        diff_scale: diff.scale,
        mask_pixels: mask.iter().filter(|&&m| m).count() as u64,
        masked: view.mask.map(|_| format!("{pair}-masked.png")),
    };
    if let (Some(m), Some(name)) = (view.mask, &out.masked) {
        let drawn = images::mask_overlay_rgb8(m, img.data_window(), &new_rgb);
        images::write_png_rgb8(&dir.join(name), w, h, &drawn)?;
    }
    let png = |name: &str, rgb: &[u8]| images::write_png_rgb8(&dir.join(name), w, h, rgb);
    png(&out.new, &new_rgb)?;
    png(&out.reference, &images::tonemap_rgb8(reference))?;
    png(&out.mask, &images::mask_rgb8(&mask, &new_rgb))?;
    png(&out.diff, &images::diff_map_rgb8(&diff, w, h))?;
    png(&out.flip, &images::heatmap_rgb8(&flip, w, h))?;
    Ok(out)
}

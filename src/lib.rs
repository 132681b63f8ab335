//! # rayproof
//!
//! Tells, with proof, how accurate and how fast ray-tracing numerics are.
//!
//! ```
//! use rayproof::audit::{audit_shape, plan::Options};
//! use rayproof::shapes::shape_by_name;
//!
//! // The chapter's quadratic solvers, 300 cases per class and precision, seed 1, judged by
//! // the built-in tolerance table (what `rayproof audit --shape quadratic --cases 300` does)
//! let shape = shape_by_name("quadratic").unwrap();
//! let opts = Options { cases: Some(300), seed: 1, ..Default::default() };
//! let report = audit_shape(shape, &opts).unwrap();
//! assert!(report.failures().is_empty(), "{:?}", report.failures());
//! // Every row carries its counts: the textbook formula's wrong verdicts are known failures
//! let textbook = report.rows.iter().filter(|r| r.method == "textbook");
//! assert!(textbook.count() > 0);
//! ```
//!
//! Terminology (after libm-test):
//! - **method**: one way to intersect a ray with a shape, written once over [`numerics::real::Real`]
//!   (e.g. [`shapes::sphere::methods::algebraic`]), instantiated for `f32` and `f64`;
//! - **oracle**: the exact answer from the inputs' exact binary values ([`shapes::sphere::oracle`]),
//!   with MPFR (through `rug`) for roots and GMP integers for signs;
//! - **class**: a named, seeded generator of hard cases whose membership the oracle confirms
//!   ([`shapes::sphere::cases::Class`]);
//! - **judgement**: how one method's answer compares with the oracle ([`audit::judge::Judgement`]);
//! - **audit**: every method × precision × class, aggregated into rows ([`audit`]), checked
//!   against one tolerance table ([`audit::tolerance`]).
//!
//! # Where the reference material is
//!
//! The README is the newcomer's guide; the reference material is in the module docs:
//! - [`audit`]: running an audit, the metrics and the harness's mutation test; the tolerance
//!   rules in [`audit::tolerance`], sharding in [`audit::shard`], replaying a case in
//!   [`audit::probe`], outside code in [`audit::api`], [`audit::exec`], [`audit::plugin`] and
//!   [`audit::offline`]; the reintersection and watertightness tests in
//!   [`audit::robustness`];
//! - [`shapes`]: the routines of Lengyel's ray-tracing chapter and an excerpt of their audit;
//!   [`shapes::sphere`]: the ray–sphere
//!   methods, case classes, findings and benchmarks;
//! - [`render`]: the renderer, its conventions and speed; [`render::export`]: how POV-Ray,
//!   Mitsuba and rayproof are made to agree;
//! - [`golden`]: golden-image CI and rayproof's own references; [`images`]: `rayproof diff`
//!   and its parity with idiff;
//! - [`implicit`]: implicit surfaces; [`render::subdiv`]: Wu & Pan's image-space subdivision,
//!   reproduced;
//! - [`report`]: `rayproof report`, what accuracy costs;
//! - [`output`]: how every output file is written; [`input`]: how input files are read within
//!   their size caps.
//!
//! # Exit codes of the `rayproof` command
//!
//! | code | meaning |
//! |---|---|
//! | 0 | success; for `audit` and `merge`, no row is out of tolerance (rows too small to tell are listed; a shard run, `--shard K/N` or `--shard-out`, leaves the table to the merge and exits 0) |
//! | 1 | `audit` or `merge` ran and some row is out of tolerance (a regression, or a known failure that stopped failing) |
//! | 2 | bad usage or input: one line on stderr names the argument (malformed number, unknown shape, method, class or precision, bad shard, unwritable output, a tolerance file with an unknown name or a dead rule); for `merge`, a shard file that is unreadable, truncated, corrupt or not a shard |
//! | 3 | `reference`: a renderer is missing (one line saying how to install it; nothing rendered) or failed, or made an image that cannot be a reference (another size than the frame, NaN or Inf; nothing written). `merge`: the shard files are not one audit's shards 0/N … N−1/N (a shard missing or given twice, or a different seed, `--cases`, selection, N, rayproof version or tolerance table), or `--tolerances` is not the table the shards were run with |
//! | 4 | `audit` or `probe` with `--exec` or `--plugin`: the outside routine failed (the child crashed, hung past `--timeout`, wrote more than its output cap, answered a line that is not an answer — not a count and numbers — or the wrong number of lines; the library routine, in its worker process, crashed, aborted, overflowed its stack, called `exit()`, hung past `--timeout`, returned non-zero or left a count unwritten; the line names the batch and, where one case does it, the case); no report is written. An answer that parses but breaks the answer contract ([`audit::contract`]) is not a failure of the routine's run but a wrong answer, counted in its row |
//! | 71 | out of memory (every command): an allocation failed, under the machine's memory or the process's address-space limit (`ulimit -v`); one line gives its size, and the run ends as an interrupt does (outside commands killed, temporaries removed, no output replaced; sysexits' `EX_OSERR`). Before, an abort with a stack trace (exit 134) |
//! | 130 | interrupted by SIGINT or SIGTERM: the temporaries of outputs being written are removed, no output is replaced |
//!
//! `spawn` uses them too: 0 when no rule given by `--exec` self-hits (the built-in rules are
//! reported), 1 when one does (and for `--replay`, when the replayed ray self-hits), 2 for bad
//! usage, 4 when an `--exec` rule's child fails or answers a line that is not `1 OX OY OZ TMIN`.
//! `guard` uses them too: 0 when no judged guard (`ize`, and every guard of yours) loses a box,
//! 1 when one does (and for `--replay`, when the replayed box is culled), 2 for bad usage, 4 when
//! a guard of yours fails or answers other than `1 HIT`. `once` reports: 0, or 2 for bad usage.
//! `builds` exits 0 when every build of the routine gives the baseline's verdicts (contraction
//! off), 1 when one flips a verdict, 2 for bad usage, a missing compiler or a source that does
//! not build, 4 when a build's routine fails as a plugin does.
//! `implicit-check` uses them too: 0 when the certified mode matches per-pixel tracing pixel for
//! pixel, 1 when it loses or adds a pixel, 2 for bad input. `downsample` exits 4 when its input
//! image is unreadable or too large, as `diff` does. `check` uses 0 when every comparison
//! passes (warnings, known failures and skipped optional references included), 1 when one fails,
//! 2 for a suite file that does not validate, and 3 when a test is refused (see [`golden`]).
//! `diff` follows idiff instead:
//!
//! | code | `rayproof diff` |
//! |---|---|
//! | 0 | PASS |
//! | 1 | WARNING |
//! | 2 | FAILURE |
//! | 3 | the images differ in display window, channels or layer (with `--idiff-compat`, which compares them over the union of their data windows as idiff does, only when `--diff-exr` or `--variance` needs them to show one frame) |
//! | 4 | an input is unreadable: missing, empty, truncated, corrupt, not EXR/PNG, or over a limit; or it has no layer `--layer` names, or several layers and none the default takes (a `Combined` layer, else one with `R`, `G`, `B`) |
//! | 64 | bad usage: an unknown option or a bad value, or an idiff option rayproof refuses (`-p`, `-a`, `-od`; sysexits' `EX_USAGE`): never a verdict's code, so a CI tells a typo from a regression |
//! | 71 | out of memory, as for every command (above) |
//! | 73 | an output that cannot be written: its directory missing, not writable, or an input (sysexits' `EX_CANTCREAT`) |
//!
//! How output files are written, and what an interrupted command leaves: [`output`].
//!
//! # Limits
//!
//! Checked up front, before anything is allocated, with one line naming the input and the limit
//! it breaks (exit 2 for scenes, arguments, suite files and tolerance tables, 4 for image files);
//! nothing is cut silently but the path tree's budget, which the render reports:
//!
//! | what | limit |
//! |---|---|
//! | image side (camera `width`/`height`, `--width`, a height made by an aspect ratio, a suite test's `width`, a manifest's `width`) | 16,384 pixels |
//! | pixels of one image, rendered or read (an EXR's declared data window, a PNG's header) | 2^26 (8192²) |
//! | samples of one image file read (pixels × channels as its header declares them, every EXR part together; a PNG as RGB or RGBA) | 2^28 (8192² × 4): a 198 KB EXR declaring 8192² × 64 channels aborted, a 16384² PNG of 261 KB took 4.2 GB |
//! | channels of one EXR file (every part and layer together) | 1,024: a file of 10,000 layers of 2×2 pixels is far under the sample limit and refused by this |
//! | an image file | a regular file of at most 1088 MiB (an uncompressed float32 EXR of 2^28 samples and its tables) |
//! | an EXR's offset table | must fit in the file (a truncated or corrupt header is refused) |
//! | what a decoder allocates beyond the pixels (a PNG's inflated `iCCP`, `zTXt`, `iTXt`) | 16 MiB ([`images::MAX_ANCILLARY_BYTES`]): a 4×4 PNG whose 1.4 MB `iCCP` inflated to 1.5 GB aborted under a 1 GB limit; the profile is dropped (rayproof reads code values as stored) |
//! | the union of two data windows compared | walked only where a file holds pixels (two 1×1 windows 10⁹ apart: milliseconds; it was allocated, an abort at 5·10⁷ apart); a per-pixel map over it (ꟻLIP, z-test, heat map, difference image, `check`'s previews) only when it holds at most 2× the files' pixels + 2¹⁶ and at most 8192² ([`images::align`]: at 4×, a mostly black union made HDR-ꟻLIP take 25 exposures, over 11 minutes), else refused with exit 3 |
//! | ꟻLIP's memory and time | tiles of about 2²⁰ pixels (≥ 256 rows; an image wider than 4096 cut into columns too) with 10 rows and columns of halo (the filters' reach), bit for bit the whole image's map; only within the reach of the pixels where the two images (and, per exposure, their codes) differ, the rest exactly 0; images narrower than 64 columns laid out by columns, bit for bit the same. `diff --flip` against idiff on the same pair, whole processes run in turn A B A B …, medians of the pair-by-pair ratios (2-core AMD EPYC without AVX-512, 24 GiB, 2026-11-29, 5 and 3 pairs of runs, a test build running beside): 3840×2160 RGBA half, CPU 2.13× idiff's and peak memory 495.4 MiB against 426.4 MiB (1.16×); 8192² RGBA half, CPU 2.48×, 2,884 MiB against 2,235 MiB (1.29×). Plain `diff` (ꟻLIP off unless asked for): CPU 0.79× and 1.10×, memory 367.5 MiB against 426.4 MiB and 1.29×. Before the bands, a 2048² RGB float pair peaked at 1,094 MB (issue 46 reported 18.1 GB at 8192²); before the cube root and the paired rows, `--flip` took 3.9× idiff's CPU at 3840×2160 |
//! | layers of an EXR test image or reference in `check` (parts, and `LAYER.CHANNEL` groups in a part) | 256: 10,000 parts of 64² took 2.2 s and 537 MB to read one of them, and 10,000 channel groups were refused in a 300 KB line ([`golden::formats::MAX_EXR_LAYERS`]) |
//! | a message about one image file in a `check` row | 400 characters |
//! | sub-pixel grid n (`camera.grid`, `--spp` = n², `--grid`, a suite test's `grid`, a manifest's `grid`) | 64 |
//! | `render.max_depth` (ray segments per path) | 256 (POV-Ray's `max_trace_level` stops at 256) |
//! | ray segments of one camera sample's path tree (primary, reflection and refraction rays) | 4096 = 2^12: never reached at `max_depth` ≤ 12 (every reference scene has ≤ 10); beyond, the rays past it are black, counted in the sidecar's `rays.budget_cut` ([`render::MAX_TREE_SEGMENTS`]). 40 glass and mirror spheres took 33 s at depth 48 without it, 0.08 s at depth 256 with it |
//! | the magnitude of any number in a scene file, and of an MPU point's coordinates | 1e150: squared distances stay finite (five MPU points at ±1e153 fit in 0.05 s; at ±1e154 their squared distances overflow and the fit had not ended after 10 s) |
//! | light `intensity`, directional `irradiance`, `render.ambient` (per channel) | `[0, 1e30]` (at 1e300, 132–143 of 16×16 pixels were Inf) |
//! | a glass's `ior` | `[0.01, 100]` (beyond about 1e154 its square overflows and pixels turned NaN: found by `tests/fuzz.rs`) |
//! | an OBJ mesh or an MPU point file | a regular file of at most 64 MiB; an OBJ gives at most 2^22 triangles; its `mtllib` is not read (materials come from the scene) |
//! | a scene file, suite file, tolerance table or manifest | 16 MiB (read up to that from a pipe) |
//! | a tolerance table's `[measured]` count `[k, n]` | n ≤ 10^7, and bounds that bracket k/n: statrs' beta quantile never returned at n ≥ about 7.9·10^6 (k near 0 or n), so the bounds are found by bisection on the CDF (under 0.2 ms); its accuracy ran out at 5·10^7 (5 of 2001 k with lower bound > k/n) |
//! | a tolerance rule's `max_err_over_cond` | a finite number ≥ 0 (NaN passed every row) |
//! | a suite's `timeout` | `(0, 604800]` seconds (one week; 1e20 made the duration panic) |
//! | `audit --cases` | none: cases are streamed, memory does not grow with it (16 MB peak measured at 10^8 per class); `cases` streams its file too (10 MB resident for 680 MB at `--cases 200000`; it held the whole file, 672 MB) |
//! | a `score` cases or answers file, a `merge` shard file | 256 MiB, read up to that from a pipe ([`input::MAX_DATA_BYTES`]): the default cases file of the sphere (360,000 cases) is 68 MB and takes 213 MB to score; `/dev/zero` as `--cases` was read until the kernel killed rayproof at 22 GB |
//! | a file whose SHA-256 is taken (a reference, a golden, a test's scene) | a regular file of at most 1088 MiB, as an image file (a scene of `/dev/zero` was read until memory ran out) |
//! | an outside command's output | `--exec`: 16 MiB of standard output per batch ([`audit::exec::STDOUT_CAP`]); a suite's or `reference`'s renderer: 256 MiB ([`process::STDOUT_CAP`]); beyond, the command is killed and the line says the cap. Standard error: its first and last 64 KiB are kept (1 GB of it became a 1 GB error line at 2.9 GB resident) |
//! | an output's file name | 255 bytes, the file system's own limit: temporaries carry the name's first 213 bytes (a 250-character name was refused, its temporary's name too long) |
//!
//! Scene values are validated once, at load, with the file, line and field in the error: every
//! position, direction and size finite (NaN and ±inf are rejected everywhere) and within ±1e150,
//! radii and sizes > 0, normals, directions and `up` non-zero and normalisable (the camera's
//! frame must come out finite), `look_at` ≠ `position`, light intensities finite in
//! `[0, 1e30]`, albedo and reflectance in `[0, 1]`, OBJ vertices finite. A rendered image has
//! no NaN or Inf pixel (a pixel above f32's range, next to a point light, is stored as f32's
//! largest value); its sidecar counts them (`nonfinite_pixels`). Numbers on the command line
//! follow one rule in decimal and hex: a literal too large for the precision or a non-zero one
//! that would round to 0 is an error (`inf`, `nan`, zeros and subnormals are values).
//!
//! # The repository around the crate
//!
//! - `tests/`: one test binary, `main.rs`, with a module per area: `sphere.rs` (one test per
//!   method × class, teeth, hand-derived oracle cases, proptest), `verdicts.rs` (other seeds
//!   and case counts pass; a robust method made naive fails), `shard.rs`, `cli.rs`,
//!   `layers.rs` (the layers point one way), and one file per other area.
//! - `benches/`: criterion benchmarks, each validated against the oracle before it times.
//! - `scripts/`: `audit-excerpt`, `audit-excerpt-routines`, `measure-tolerances`, `bench-render`,
//!   `bench-outside`, `make-fan30`, `make-seed1996`, the reference scripts (`render-povray`,
//!   `render-mitsuba`, `render-references`, `verify-references`, `mitsuba_whitted.py`,
//!   `reflib.sh`), `check-table`, `idiff-pairs`, `fetch-bunny`,
//!   `bench-implicit`, `mutate` (the harness's mutation test, see [`audit`]).
//! - `reference/`: the scene files, the golden images, their manifests and `suite.toml`;
//!   `reference/report/`: one full `rayproof report` run, the figures the README shows.

#![warn(missing_docs)]
pub mod audit;
pub mod golden;
pub mod images;
pub mod implicit;
pub mod input;
pub mod numerics;
pub mod output;
pub mod process;
pub mod render;
pub mod report;
pub mod shapes;

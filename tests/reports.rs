//! The reports of `rayproof check` as CI servers and people read them (issue 36 items 5 and 6,
//! issue 38 item 5):
//! - the JUnit file of a suite with every kind of row (pass, failure, NaN failure, refused by a
//!   crash and by a timeout, new, skipped, XFAIL, XPASS) validates with the real `xmllint
//!   --schema` against `tests/data/junit-10.xsd`; its times add up and count each render once;
//!   failures carry a body with the metrics, thresholds, replay command and renderer log;
//! - the status table: every status → its JUnit element, `type`, message and count;
//! - the HTML report of a 1e-6 change: the failing-pixel mask and the normalised |difference|
//!   map are there and show it, the maximum is ringed, the header has the terminal's counts.
//!
//! The XML is read back with Python's `xml.etree` (an independent parser); `xmllint` must be
//! installed (Debian `libxml2-utils`): without it the tests fail, they do not skip.

use rayproof::golden::{junit, Row, Rule, Status};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

fn standin() -> String {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/outside/standin_render.py");
    format!("python3 '{}'", p.display())
}

fn xsd() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/junit-10.xsd")
}

/// `xmllint --noout --schema junit-10.xsd FILE`: Ok, or its complaint.
fn xmllint(file: &Path) -> Result<(), String> {
    let o = Command::new("xmllint")
        .arg("--noout")
        .arg("--schema")
        .arg(xsd())
        .arg(file)
        .output()
        .unwrap_or_else(|e| {
            panic!("cannot run xmllint ({e}): install it (Debian: apt-get install libxml2-utils)")
        });
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    if o.status.success() && err.contains("validates") {
        Ok(())
    } else {
        Err(err)
    }
}

/// The JUnit file as JSON, read by Python's `xml.etree`: the `<testsuites>` and `<testsuite>`
/// attributes, and per case its attributes and children (tag, attributes, text).
fn parse(xml: &str) -> Value {
    const SCRIPT: &str = r#"
import json, sys, xml.etree.ElementTree as ET
root = ET.fromstring(sys.stdin.buffer.read())
suite = root.find("testsuite")
kids = lambda e: [{"tag": k.tag, "attrs": k.attrib, "text": k.text or ""} for k in e]
print(json.dumps({"testsuites": root.attrib, "testsuite": suite.attrib,
                  "suites": len(root.findall("testsuite")),
                  "cases": [{"attrs": c.attrib, "children": kids(c)} for c in suite.findall("testcase")]}))
"#;
    let mut child = Command::new("python3")
        .arg("-c")
        .arg(SCRIPT)
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    use std::io::Write;
    child
        .stdin
        .take()
        .unwrap()
        .write_all(xml.as_bytes())
        .unwrap();
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "python could not parse:\n{xml}");
    serde_json::from_slice(&o.stdout).unwrap()
}

/// The case named `name`, and its one status child (`failure`, `error`, `skipped`), if any.
fn case<'a>(doc: &'a Value, name: &str) -> (&'a Value, Option<&'a Value>) {
    let c = doc["cases"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["attrs"]["name"] == name)
        .unwrap_or_else(|| panic!("no case {name} in {doc}"));
    let status: Vec<&Value> = c["children"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|k| ["failure", "error", "skipped"].contains(&k["tag"].as_str().unwrap()))
        .collect();
    assert!(status.len() <= 1, "{c}");
    (c, status.first().copied())
}

/// A case's time in whole milliseconds (the file writes three decimals).
fn ms(v: &Value) -> u64 {
    let s = v.as_str().unwrap();
    let (a, b) = s.split_once('.').unwrap_or_else(|| panic!("time {s}"));
    assert_eq!(b.len(), 3, "time {s}");
    a.parse::<u64>().unwrap() * 1000 + b.parse::<u64>().unwrap()
}

fn check(dir: &Path, args: &[&str]) -> (Option<i32>, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_rayproof"))
        .current_dir(dir)
        .arg("check")
        .arg("--suite")
        .arg("suite.toml")
        .args(args)
        .output()
        .unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// A scratch directory with `refs/a.exr` made by the stand-in (48 wide, 2×2 grid).
fn scratch(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rayproof-reports-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("refs")).unwrap();
    let st = Command::new("sh")
        .arg("-c")
        .arg(format!("{} refs/a.exr --width 48 --grid 2", standin()))
        .current_dir(&dir)
        .status()
        .unwrap();
    assert!(st.success());
    dir
}

#[test]
fn the_junit_of_every_kind_of_row_validates_and_adds_up() {
    let dir = scratch("junit");
    let r = format!("{} {{out}} --width 48 --grid 2", standin());
    let ext = r#"reference = [{ name = "ext", path = "refs/a.exr" }]"#;
    let suite = format!(
        r#"[suite]
name = "every <kind> & row"
renderer = "{r}"
goldens = "goldens"
timeout = 8

[thresholds]
fail = 0.01
failpercent = 0.1

[[test]]
name = "pass"
golden = false
{ext}

[[test]]
name = "fail"
golden = false
command = "printf 'loading scene\\n\\033[31mwarning: GPU <slow> & hot\\033[0m\\n' >&2; {r} --perturb 0.2"
{ext}

[[test]]
name = "nan"
golden = false
command = "{r} --nan"
{ext}

[[test]]
name = "crash"
golden = false
command = "{r} --fail"
{ext}

[[test]]
name = "hang"
golden = false
command = "{r} --hang"
{ext}

[[test]]
name = "new"
command = "sleep 0.5; {r}"
reference = [{{ name = "opt", path = "refs/missing.exr", required = false }}]

[[test]]
name = "xfail"
golden = false
command = "{r} --perturb 0.2"
thresholds = {{ known_failure = "the disc's edge moved (issue 12)" }}
{ext}

[[test]]
name = "xpass"
golden = false
thresholds = {{ known_failure = "a flaky shadow (issue 13)" }}
{ext}

[[test]]
name = "slow"
golden = false
command = "sleep 1; {r}"
reference = [{{ name = "e1", path = "refs/a.exr" }}, {{ name = "e2", path = "refs/a.exr" }}, {{ name = "e3", path = "refs/a.exr" }}]
"#
    );
    std::fs::write(dir.join("suite.toml"), suite).unwrap();
    let t0 = std::time::Instant::now();
    let (code, out, err) = check(&dir, &["--junit", "junit.xml"]);
    let wall_ms = t0.elapsed().as_millis() as u64;
    assert_eq!(code, Some(3), "{out}{err}");
    let file = dir.join("junit.xml");
    let xml = std::fs::read_to_string(&file).unwrap();

    // The real xmllint accepts it
    if let Err(e) = xmllint(&file) {
        panic!("xmllint rejects the JUnit file: {e}\n{xml}");
    }
    let doc = parse(&xml);
    assert_eq!(doc["suites"], 1, "{xml}");

    // Every kind of row, as the status table says
    let want = [
        ("pass vs ext [command]", None, ""),
        ("fail vs ext [command]", Some("failure"), "FAILURE"),
        ("nan vs ext [command]", Some("failure"), "FAILURE"),
        ("crash vs ext [command]", Some("error"), "REFUSED"),
        ("hang vs ext [command]", Some("error"), "REFUSED"),
        ("new vs golden [command]", Some("failure"), "NEW"),
        ("new vs opt [command]", Some("skipped"), "SKIPPED"),
        ("xfail vs ext [command]", Some("skipped"), "XFAIL"),
        ("xpass vs ext [command]", Some("failure"), "XPASS"),
    ];
    for (name, element, kind) in want {
        let (_, child) = case(&doc, name);
        assert_eq!(child.map(|c| c["tag"].as_str().unwrap()), element, "{name}");
        if let Some(c) = child {
            assert_eq!(c["attrs"]["type"], kind, "{name}");
        }
    }
    let attr = |c: Option<&Value>, k: &str| c.unwrap()["attrs"][k].as_str().unwrap().to_string();
    let text = |c: Option<&Value>| c.unwrap()["text"].as_str().unwrap().to_string();
    // Messages: the NaN failure says NaN, XFAIL gives its reason, XPASS says it now passes
    let (_, nan) = case(&doc, "nan vs ext [command]");
    assert!(
        attr(nan, "message").contains("NaN"),
        "{}",
        attr(nan, "message")
    );
    let (_, xfail) = case(&doc, "xfail vs ext [command]");
    assert_eq!(
        attr(xfail, "message"),
        "XFAIL (expected failure): the disc's edge moved (issue 12)"
    );
    let (_, xpass) = case(&doc, "xpass vs ext [command]");
    assert!(
        attr(xpass, "message").starts_with("XPASS (a known failure now passes): "),
        "{}",
        attr(xpass, "message")
    );
    // The failure's body: metrics, thresholds, replay, the renderer's log (escape codes made
    // visible, markup escaped and read back as written)
    let (_, fail) = case(&doc, "fail vs ext [command]");
    assert_eq!(
        attr(fail, "message"),
        "FAILURE: 64 px (4.167 %) over fail 0.01"
    );
    let body = text(fail);
    for part in [
        "metrics: mean 8.333e-3, RMS 4.082e-2",
        "64 px (4.167 %) over fail",
        "thresholds: fail 0.01 failrelative 0 failpercent 0.1",
        "replay: rayproof check --suite suite.toml --test fail\n",
        // Its warning, not its chatter ("loading scene"): the lines that explain
        "renderer log (the lines that explain how it ended, 20 at most):\n\\u{1b}[31mwarning: GPU <slow> & hot\\u{1b}[0m\n",
    ] {
        assert!(body.contains(part), "no {part:?} in the body:\n{body}");
    }
    // A crash's log tail is in its <error>, and XFAIL's <skipped> has the metrics too
    let (_, crash) = case(&doc, "crash vs ext [command]");
    assert!(
        text(crash).contains("standin: out of memory (pretend)"),
        "{}",
        text(crash)
    );
    assert!(
        text(xfail).contains("metrics: mean 8.333e-3"),
        "{}",
        text(xfail)
    );

    // Counts: skipped only on <testsuite>, as junit-10.xsd allows
    let (ts, s) = (&doc["testsuites"], &doc["testsuite"]);
    assert_eq!(ts["name"], "every <kind> & row");
    assert!(ts.get("skipped").is_none(), "{ts}");
    for (k, v) in [("tests", "12"), ("failures", "4"), ("errors", "2")] {
        assert_eq!(ts[k], v, "testsuites {k}");
        assert_eq!(s[k], v, "testsuite {k}");
    }
    assert_eq!(s["skipped"], "2");

    // Times: the suite's is the sum of its cases', within the run's wall time; a render is on
    // one of its test's cases, not repeated on each
    let cases = doc["cases"].as_array().unwrap();
    let sum: u64 = cases.iter().map(|c| ms(&c["attrs"]["time"])).sum();
    assert_eq!(ms(&s["time"]), sum, "{xml}");
    assert_eq!(ms(&ts["time"]), sum, "{xml}");
    assert!(
        sum <= wall_ms,
        "cases add up to {sum} ms, the run took {wall_ms} ms"
    );
    let time = |name: &str| ms(&case(&doc, name).0["attrs"]["time"]);
    let slow: Vec<u64> = ["e1", "e2", "e3"]
        .iter()
        .map(|e| time(&format!("slow vs {e} [command]")))
        .collect();
    // The 1 s render is on the first comparison only; the others are comparisons of a 48-pixel
    // image, which cannot hold the render's 1 s sleep (no upper bound on the render itself:
    // a loaded machine may take any time to start the stand-in)
    assert!(
        slow[0] >= 1000 && slow[1] < 1000 && slow[2] < 1000,
        "a 1 s render over three comparisons: {slow:?}"
    );
    // NEW and REFUSED are timed: the 0.5 s render of a missing golden, the 8 s timeout (the
    // timeout is long enough that no working render of this suite meets it under load)
    assert!(time("new vs golden [command]") >= 500, "{xml}");
    assert_eq!(time("new vs opt [command]"), 0, "{xml}");
    let hang = time("hang vs ext [command]");
    assert!(
        hang >= 8000 && hang <= wall_ms,
        "an 8 s timeout shows {hang} ms (the run took {wall_ms} ms)"
    );
}

/// A row of the given status, as `check` makes them.
fn row(status: Status, note: &str) -> Row {
    Row {
        test: format!("t-{}", status.label()),
        reference: "ref".into(),
        renderer: String::new(),
        config: "command".into(),
        status,
        note: note.into(),
        warnings: vec![],
        comparison: None,
        ztest: None,
        rule: Rule::from_layers(&[]).unwrap(),
        render_seconds: 0.25,
        seconds: 0.25,
        replay: "rayproof check --suite s.toml --test t".into(),
        log_tail: Some("last line".into()),
        images: None,
        stale: None,
        log: None,
        platform: None,
        mask: None,
    }
}

#[test]
fn the_status_table_every_status_to_its_junit_element() {
    // (status, element, type, message start, counted as)
    let table = [
        (Status::Pass, None, "", "", "pass"),
        (Status::Warning, None, "", "", "pass"),
        (Status::Updated, None, "", "", "pass"),
        (
            Status::Failure,
            Some("failure"),
            "FAILURE",
            "FAILURE: ",
            "failures",
        ),
        (
            Status::UnexpectedPass,
            Some("failure"),
            "XPASS",
            "XPASS (a known failure now passes): ",
            "failures",
        ),
        (Status::New, Some("failure"), "NEW", "NEW: ", "failures"),
        (
            Status::Refused,
            Some("error"),
            "REFUSED",
            "REFUSED: ",
            "errors",
        ),
        (
            Status::KnownFailure,
            Some("skipped"),
            "XFAIL",
            "XFAIL (expected failure): ",
            "skipped",
        ),
        (
            Status::Skipped,
            Some("skipped"),
            "SKIPPED",
            "SKIPPED: ",
            "skipped",
        ),
    ];
    let rows: Vec<Row> = table.iter().map(|t| row(t.0, "why")).collect();
    let xml = junit(&rows, "table");
    let file =
        std::env::temp_dir().join(format!("rayproof-status-table-{}.xml", std::process::id()));
    std::fs::write(&file, &xml).unwrap();
    if let Err(e) = xmllint(&file) {
        panic!("xmllint rejects the JUnit file: {e}\n{xml}");
    }
    let doc = parse(&xml);
    for (status, element, kind, message, _) in table {
        let name = format!("t-{} vs ref [command]", status.label());
        let (c, child) = case(&doc, &name);
        assert_eq!(c["attrs"]["classname"], format!("t-{}", status.label()));
        assert_eq!(c["attrs"]["time"], "0.250", "{name}");
        assert_eq!(child.map(|k| k["tag"].as_str().unwrap()), element, "{name}");
        if let Some(k) = child {
            assert_eq!(k["attrs"]["type"], kind, "{name}");
            assert_eq!(k["attrs"]["message"], format!("{message}why"), "{name}");
            // A body for all but a missing optional reference, whose message is all there is
            let body = k["text"].as_str().unwrap();
            if status == Status::Skipped {
                assert_eq!(body, "", "{name}");
            } else {
                for part in [
                    "metrics: none",
                    "thresholds: fail",
                    "replay: rayproof check",
                    "last line",
                ] {
                    assert!(body.contains(part), "{name}: no {part:?} in {body}");
                }
            }
        }
        // The renderer's log: in the body when there is one, else in <system-err>
        let err = c["children"]
            .as_array()
            .unwrap()
            .iter()
            .any(|k| k["tag"] == "system-err" && k["text"] == "last line");
        assert_eq!(err, matches!(element, None | Some("skipped")), "{name}");
    }
    let count = |what: &str| table.iter().filter(|t| t.4 == what).count().to_string();
    let (ts, s) = (&doc["testsuites"], &doc["testsuite"]);
    for k in ["failures", "errors"] {
        assert_eq!(ts[k], count(k), "{k}");
        assert_eq!(s[k], count(k), "{k}");
    }
    assert_eq!(s["skipped"], count("skipped"));
    assert!(ts.get("skipped").is_none());
    assert_eq!(
        (&ts["tests"], &s["tests"]),
        (&Value::from("9"), &Value::from("9"))
    );
    assert_eq!(
        (&ts["time"], &s["time"]),
        (&Value::from("2.250"), &Value::from("2.250"))
    );
}

/// The `<img class="CLASS" src="…">` of the table row that starts with `<b>TEST</b><br>vs REF`.
fn img_in_row<'a>(page: &'a str, test: &str, reference: &str, class: &str) -> &'a str {
    let start = page
        .find(&format!("<td><b>{test}</b><br>vs {reference}"))
        .unwrap_or_else(|| panic!("no {test} vs {reference} row"));
    let tr = &page[start..start + page[start..].find("</tr>").unwrap()];
    let at = tr
        .find(&format!("<img class=\"{class}\" src=\""))
        .unwrap_or_else(|| panic!("no {class} image in {tr}"));
    let rest = &tr[at + class.len() + 19..];
    &rest[..rest.find('"').unwrap()]
}

#[test]
fn the_html_report_shows_a_one_in_a_million_change() {
    // A golden blessed, then the renderer adds 1e-6 to an 8×8 block: the golden comparison
    // (fail = 1e-7) fails on exactly those 64 pixels; beside it a failing test and a refused one
    let dir = scratch("html");
    let r = format!("{} {{out}} --width 48 --grid 2", standin());
    let suite = format!(
        r#"[suite]
name = "one-in-a-million"
renderer = "{r}"
goldens = "goldens"
timeout = 8

[thresholds]
fail = 0.01
failpercent = 0.1

[golden_thresholds]
fail = 1e-7

[[test]]
name = "disc"
reference = [{{ name = "ext", path = "refs/a.exr" }}]

[[test]]
name = "moved"
golden = false
command = "{r} --perturb 0.2"
reference = [{{ name = "ext", path = "refs/a.exr" }}]

[[test]]
name = "hang"
golden = false
command = "{r} --hang"
reference = [{{ name = "ext", path = "refs/a.exr" }}]
"#
    );
    std::fs::write(dir.join("suite.toml"), &suite).unwrap();
    let (code, out, err) = check(&dir, &["--test", "disc", "--update"]);
    assert_eq!(code, Some(0), "{out}{err}");
    std::fs::write(
        dir.join("suite.toml"),
        suite.replacen(
            &format!("renderer = \"{r}\""),
            &format!("renderer = \"{r} --perturb 1e-6\""),
            1,
        ),
    )
    .unwrap();
    let (code, out, err) = check(&dir, &["--report", "html"]);
    assert_eq!(code, Some(3), "{out}{err}");
    // The header's counts are the terminal's
    assert!(out.contains("4 comparisons in"), "{out}");
    assert!(out.contains(": 2 failing, 1 refused\n"), "{out}");
    let page = std::fs::read_to_string(dir.join("html/index.html")).unwrap();
    assert!(
        page.contains("<p class=\"counts\">4 comparisons: 2 failing, 1 refused.</p>"),
        "{page}"
    );
    // No empty labels
    assert!(
        !page.contains("()") && !page.contains("<small></small>"),
        "{page}"
    );

    // The mask: exactly the 64 failing pixels red, where the block is
    let png = |name: &str| image::open(dir.join("html").join(name)).unwrap().to_rgb8();
    let mask = png(img_in_row(&page, "disc", "golden", "mask"));
    let red: Vec<(u32, u32)> = mask
        .enumerate_pixels()
        .filter(|(_, _, p)| p.0 == [255, 0, 0])
        .map(|(x, y, _)| (x, y))
        .collect();
    assert_eq!(red.len(), 64, "failing pixels in the mask");
    assert!(red
        .iter()
        .all(|&(x, y)| (4..12).contains(&x) && (4..12).contains(&y)));
    assert!(page.contains("64 px over fail 0.0000001"), "{page}");
    // The rest of the mask is the picture, dimmed: not one flat colour
    let greys: std::collections::BTreeSet<[u8; 3]> = mask.pixels().map(|p| p.0).collect();
    assert!(greys.len() > 10, "{} colours", greys.len());

    // The |difference| map: the block bright (the scale is the 1e-6 change), the rest black
    let diff = png(img_in_row(&page, "disc", "golden", "diff"));
    let bright = |p: &image::Rgb<u8>| p.0.iter().map(|&v| v as u32).sum::<u32>() > 300;
    for (x, y, p) in diff.enumerate_pixels() {
        let inside = (4..12).contains(&x) && (4..12).contains(&y);
        assert_eq!(bright(p), inside, "({x}, {y}): {:?}", p.0);
    }
    let scale = page
        .split("scale: pale yellow = ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .unwrap_or_else(|| panic!("no printed scale in {page}"));
    let scale: f64 = scale.parse().unwrap();
    assert!((0.9e-6..1.1e-6).contains(&scale), "scale {scale}");
    // The ꟻLIP map alone would not show it: nearly black everywhere
    let flip = png(img_in_row(&page, "disc", "golden", "flip"));
    assert!(
        !flip.pixels().any(bright),
        "the ꟻLIP map shows the change after all"
    );

    // The maximum's ring, at the reported position, on the mask and the map
    let line = out
        .lines()
        .find(|l| l.starts_with("disc ") && l.contains("golden"))
        .unwrap();
    assert!(line.contains("FAILURE"), "{line}");
    let start = page.find("<td><b>disc</b><br>vs golden").unwrap();
    let tr = &page[start..start + page[start..].find("</tr>").unwrap()];
    let at = tr.split(" @ (").nth(1).unwrap();
    let xy: Vec<f64> = at.split(", ").take(2).map(|v| v.parse().unwrap()).collect();
    assert!(
        (4.0..12.0).contains(&xy[0]) && (4.0..12.0).contains(&xy[1]),
        "{at}"
    );
    let ring = format!(
        "<span class=\"max\" style=\"left: {:.3}%; top: {:.3}%\"",
        100.0 * (xy[0] + 0.5) / 48.0,
        100.0 * (xy[1] + 0.5) / 32.0
    );
    assert_eq!(tr.matches(&ring).count(), 2, "{ring} in {tr}");
}

//! `rayproof guard` (issue 49, item 1): the box that guards the primitive. Boxes that hold a
//! triangle's exact hit, `t_max` = that hit rounded: the naive slab test and the strict
//! comparisons of Williams et al. and pbrt-v4 cull boxes whose entry face holds the hit (lost
//! geometry), Ize's robust traversal culls none; every lost case replays.

use crate::common::{rayproof, stderr, stdout};

#[test]
fn the_naive_slab_loses_face_hits_and_izes_traversal_loses_none() {
    let dir = crate::common::temp_dir("guard");
    let json = dir.join("g.json");
    let o = rayproof(&["guard", "--per-cell", "8", "--json", json.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("verdict: pass"));
    let rows: Vec<serde_json::Value> =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(rows.len(), 4 * 4 * 2);
    let lost = |g: &str, class: &str| -> u64 {
        rows.iter()
            .filter(|r| r["guard"] == g && r["class"] == class)
            .map(|r| r["lost"].as_u64().unwrap())
            .sum()
    };
    for class in ["inside", "tight", "on_face", "grazing"] {
        assert_eq!(lost("ize", class), 0, "ize {class}");
        // A box that holds the triangle with room to spare is never lost
        if class == "inside" {
            for g in ["naive_slab", "williams", "pbrt"] {
                assert_eq!(lost(g, class), 0, "{g} {class}");
            }
        }
    }
    for g in ["naive_slab", "williams", "pbrt"] {
        assert!(lost(g, "on_face") > 0, "{g} loses no face hit");
    }
    // Every lost case replays: the guard culls it, Ize's lets it in
    for r in rows.iter().filter(|r| r["lost"].as_u64() > Some(0)) {
        let line = r["replay"].as_str().unwrap();
        let args: Vec<&str> = line.split(' ').skip(1).collect();
        let o = rayproof(&args);
        assert_eq!(o.status.code(), Some(1), "{line}: {}", stdout(&o));
        assert!(stdout(&o).contains("MISS"), "{line}");
        let mut ize = args.clone();
        ize[2] = "ize";
        let o = rayproof(&ize);
        assert_eq!(o.status.code(), Some(0), "{line}: {}", stdout(&o));
    }
    // Bad input: one line, exit 2
    for bad in [
        &["guard", "--guard", "nope"][..],
        &["guard", "--per-cell", "0"],
        &[
            "guard", "--replay", "ize", "f32", "0x1p+0", "1", "1", "1", "1", "1", "1", "1", "1",
            "1", "1", "1", "0.1",
        ],
    ] {
        let o = rayproof(bad);
        assert_eq!(o.status.code(), Some(2), "{bad:?}: {}", stderr(&o));
        assert_eq!(
            stderr(&o).trim_end().lines().count(),
            1,
            "{bad:?}: {}",
            stderr(&o)
        );
    }
}

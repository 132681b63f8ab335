//! A scene turned into geometry: objects, their bounding-volume tree, and the materials.

use super::*;

/// Builds the geometry list from the scene (materials by index).
pub fn build_geometry(s: &Scene) -> (Geometry, Vec<Material>) {
    let names: Vec<&String> = s.file.materials.keys().collect();
    let materials = s.file.materials.values().cloned().collect();
    let mi = |n: &String| names.iter().position(|k| *k == n).unwrap_or(0);
    let v = |a: [f64; 3]| DVec3::from_array(a);
    let (mut objects, mut planes, mut marchers) = (vec![], vec![], vec![]);
    for (i, sh) in s.file.shapes.iter().enumerate() {
        let material = mi(sh.material());
        match sh {
            Shape::Sphere { center, radius, .. } => objects.push(Object {
                prim: Prim::Sphere {
                    c: v(*center),
                    r: *radius,
                },
                material,
            }),
            Shape::Disc {
                center,
                normal,
                radius,
                ..
            } => objects.push(Object {
                prim: Prim::Disc {
                    c: v(*center),
                    n: v(*normal).normalize(),
                    r: *radius,
                },
                material,
            }),
            Shape::Plane { point, normal, .. } => planes.push(Plane {
                p: v(*point),
                n: v(*normal).normalize(),
                material,
            }),
            Shape::Mesh { .. } => {
                for t in &s.meshes[&i] {
                    let (a, b, c) = (v(t[0]), v(t[1]), v(t[2]));
                    objects.push(Object {
                        prim: Prim::Tri {
                            v0: a,
                            e1: b - a,
                            e2: c - a,
                        },
                        material,
                    });
                }
            }
            Shape::Box { min, max, .. } => objects.push(Object {
                prim: Prim::Box {
                    lo: v(*min),
                    hi: v(*max),
                },
                material,
            }),
            Shape::Cylinder {
                base,
                radius,
                height,
                ..
            } => {
                // Lateral surface and two cap discs, normals outward
                let b = v(*base);
                let top = b + DVec3::Y * *height;
                let side = Prim::CylinderSide {
                    base: b,
                    r: *radius,
                    h: *height,
                };
                let caps =
                    [(b, -DVec3::Y), (top, DVec3::Y)].map(|(c, n)| Prim::Disc { c, n, r: *radius });
                for prim in std::iter::once(side).chain(caps) {
                    objects.push(Object { prim, material });
                }
            }
            Shape::Ellipsoid { center, radii, .. } => objects.push(Object {
                prim: Prim::Ellipsoid {
                    c: v(*center),
                    radii: v(*radii),
                },
                material,
            }),
            Shape::Torus {
                center,
                major,
                minor,
                ..
            } => objects.push(Object {
                prim: Prim::Torus {
                    c: v(*center),
                    major: *major,
                    minor: *minor,
                },
                material,
            }),
            Shape::Sdf { .. } | Shape::Blob { .. } | Shape::Mpu { .. } => {
                let m = crate::implicit::march::Marcher::new(vec![s.implicits[&i].clone()]);
                let pad = 2.0 * (m.hi - m.lo).length() * 0.01;
                objects.push(Object {
                    prim: Prim::Implicit {
                        k: marchers.len(),
                        lo: m.lo - pad,
                        hi: m.hi + pad,
                    },
                    material,
                });
                marchers.push(m);
            }
        }
    }
    (
        Geometry::new(objects, planes).with_marchers(marchers),
        materials,
    )
}

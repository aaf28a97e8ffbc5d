//! Wavefront OBJ loading through `tobj`, with line-accurate errors.
use crate::{Error, Result};
use glam::Vec3;
use std::path::Path;

/// Loads every polygon of an OBJ file as triangles (polygons are fan-triangulated by `tobj`), in
/// the file's own coordinates. Errors name the file and, where it can be found, the line.
pub fn load_obj_triangles(path: &Path) -> Result<Vec<[Vec3; 3]>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::Obj {
        path: path.to_path_buf(),
        line: None,
        reason: format!("cannot read: {e}"),
    })?;
    // tobj's errors carry no line numbers: scan first for what it would reject, so the message can
    // point at the line.
    prescan(path, &text)?;
    let opts = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ..Default::default()
    };
    let (models, _) = tobj::load_obj_buf(&mut text.as_bytes(), &opts, |_| {
        Err(tobj::LoadError::OpenFileFailed) // materials are not part of the scene model
    })
    .map_err(|e| Error::Obj {
        path: path.to_path_buf(),
        line: None,
        reason: e.to_string(),
    })?;
    let mut tris = Vec::new();
    for m in &models {
        let p = &m.mesh.positions;
        let idx = &m.mesh.indices;
        let vert = |i: u32| -> Result<Vec3> {
            let i = i as usize * 3;
            match p.get(i..i + 3) {
                Some(s) => Ok(Vec3::new(s[0], s[1], s[2])),
                None => Err(Error::Obj {
                    path: path.to_path_buf(),
                    line: None,
                    reason: "face index out of range".into(),
                }),
            }
        };
        for f in idx.chunks_exact(3) {
            tris.push([vert(f[0])?, vert(f[1])?, vert(f[2])?]);
        }
    }
    if tris.is_empty() {
        return Err(Error::Obj {
            path: path.to_path_buf(),
            line: None,
            reason: "no faces".into(),
        });
    }
    Ok(tris)
}

/// A line's fields after its keyword, or the reason "`needs`, got N" when there are fewer than 3.
fn at_least_three<'a>(
    fields: impl Iterator<Item = &'a str>,
    needs: &str,
) -> std::result::Result<Vec<&'a str>, String> {
    let fields: Vec<&str> = fields.collect();
    if fields.len() < 3 {
        return Err(format!("{needs}, got {}", fields.len()));
    }
    Ok(fields)
}

fn prescan(path: &Path, text: &str) -> Result<()> {
    let mut nv: i64 = 0;
    for (ln, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("").trim();
        let err = |reason: String| Error::Obj {
            path: path.to_path_buf(),
            line: Some(ln + 1),
            reason,
        };
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let vals = at_least_three(it, "vertex needs 3 coordinates").map_err(err)?;
                for s in &vals[..3] {
                    match s.parse::<f32>() {
                        Ok(x) if x.is_finite() => {}
                        _ => {
                            return Err(err(format!(
                                "vertex coordinate {s:?} is not a finite number"
                            )))
                        }
                    }
                }
                nv += 1;
            }
            Some("f") => {
                let refs = at_least_three(it, "face needs at least 3 vertices").map_err(err)?;
                for r in refs {
                    let first = r.split('/').next().unwrap_or("");
                    let i: i64 = first
                        .parse()
                        .map_err(|_| err(format!("face vertex {r:?} is not an index")))?;
                    let resolved = if i < 0 { nv + 1 + i } else { i };
                    if i == 0 || resolved < 1 || resolved > nv {
                        return Err(err(format!(
                            "face vertex index {i} out of range (1..={nv} defined so far)"
                        )));
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

//! glTF 2.0 loading through the `gltf` crate, as the scene contract defines it
//! (`docs/methods.md` §11): every triangle primitive of the file's
//! default scene (scene 0 when none is marked), each in its node's world transform, in the
//! file's own units. `.gltf` files with their buffers (files beside it or `data:` URIs) and `.glb`
//! files (the `BIN` chunk) alike. Errors name the file and what is wrong, in one line
//! ([`Error::Gltf`]): unreadable, truncated or not glTF, a buffer missing or shorter than its
//! views, an accessor past its view, a primitive mode other than triangles (named), an index
//! past the positions, a non-finite position or transform, no triangles.
use crate::{Error, Result};
use base64::Engine as _;
use glam::{Mat4, Vec3};
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;
use std::path::Path;

/// Loads the triangles of a glTF 2.0 file (`.gltf` or `.glb`) in world space of the file's
/// default scene. Errors: [`Error::Gltf`] naming the file.
pub fn load_gltf_triangles(path: &Path) -> Result<Vec<[Vec3; 3]>> {
    let err = |reason: String| Error::Gltf {
        path: path.to_path_buf(),
        reason: reason.replace('\n', " "),
    };
    let bytes = std::fs::read(path).map_err(|e| err(format!("cannot read: {e}")))?;
    let doc = gltf::Gltf::from_slice(&bytes).map_err(|e| err(describe(&e)))?;
    let buffers = load_buffers(path, &doc).map_err(err)?;
    check_views(&doc, &buffers).map_err(err)?;
    let scene = doc
        .default_scene()
        .or_else(|| doc.scenes().next())
        .ok_or_else(|| err("the file has no scene".into()))?;
    let mut tris = Vec::new();
    // Depth-first over the scene's node trees, each node's world matrix its parent's times its
    // own (glTF: column-major, T * R * S).
    let mut stack: Vec<(gltf::Node<'_>, Mat4)> =
        scene.nodes().map(|n| (n, Mat4::IDENTITY)).collect();
    let mut visited = 0usize;
    while let Some((node, parent)) = stack.pop() {
        visited += 1;
        if visited > doc.nodes().len().max(1) * 64 {
            return Err(err("the node hierarchy has a cycle".into()));
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        if !world.is_finite() {
            return Err(err(format!(
                "node {} has a non-finite transform",
                node_name(&node)
            )));
        }
        if let Some(mesh) = node.mesh() {
            for (k, prim) in mesh.primitives().enumerate() {
                let at = || {
                    format!(
                        "primitive {k} of mesh {}",
                        mesh.name()
                            .map(|n| format!("{n:?}"))
                            .unwrap_or_else(|| mesh.index().to_string())
                    )
                };
                if prim.mode() != Mode::Triangles {
                    return Err(err(format!(
                        "{}: mode {:?}; only triangles (mode 4) are supported",
                        at(),
                        prim.mode()
                    )));
                }
                // The checks above keep the reader in bounds; a panic inside the `gltf` crate on
                // a file they missed is still one line, never a crash.
                let read = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    read_primitive(&prim, &buffers, world, &mut tris)
                }))
                .unwrap_or_else(|_| Err("the glTF reader failed on this primitive".into()));
                read.map_err(|e| err(format!("{}: {e}", at())))?;
            }
        }
        for child in node.children() {
            stack.push((child, world));
        }
    }
    if tris.is_empty() {
        return Err(err("no triangles in the default scene".into()));
    }
    Ok(tris)
}

/// A one-line account of a `gltf` crate error.
fn describe(e: &gltf::Error) -> String {
    match e {
        gltf::Error::Validation(list) => {
            let first: Vec<String> = list
                .iter()
                .take(3)
                .map(|(path, what)| format!("{path}: {what}"))
                .collect();
            format!(
                "invalid glTF ({} problem{}): {}",
                list.len(),
                if list.len() == 1 { "" } else { "s" },
                first.join("; ")
            )
        }
        other => format!("not a readable glTF 2.0 file: {other}"),
    }
}

fn node_name(node: &gltf::Node<'_>) -> String {
    node.name()
        .map(|n| format!("{n:?}"))
        .unwrap_or_else(|| node.index().to_string())
}

/// Every buffer's bytes: the `BIN` chunk of a `.glb`, a `data:` URI (base64), or a file
/// relative to the glTF file. Each must hold at least its declared `byteLength`.
fn load_buffers(path: &Path, doc: &gltf::Gltf) -> std::result::Result<Vec<Vec<u8>>, String> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut out = Vec::new();
    for b in doc.buffers() {
        let data = match b.source() {
            gltf::buffer::Source::Bin => doc.blob.clone().ok_or_else(|| {
                format!("buffer {} refers to a BIN chunk the file lacks", b.index())
            })?,
            gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                let (_, payload) = uri.split_once(";base64,").ok_or_else(|| {
                    format!("buffer {}: a data URI that is not base64", b.index())
                })?;
                base64::engine::general_purpose::STANDARD
                    .decode(payload)
                    .map_err(|e| format!("buffer {}: bad base64: {e}", b.index()))?
            }
            gltf::buffer::Source::Uri(uri) => {
                let file = dir.join(uri);
                std::fs::read(&file).map_err(|e| {
                    format!(
                        "buffer {} ({}): cannot read: {e}",
                        b.index(),
                        file.display()
                    )
                })?
            }
        };
        if data.len() < b.length() {
            return Err(format!(
                "buffer {} holds {} bytes, its byteLength is {}",
                b.index(),
                data.len(),
                b.length()
            ));
        }
        out.push(data);
    }
    Ok(out)
}

/// Every buffer view inside its buffer's bytes (the reader slices without checking).
fn check_views(doc: &gltf::Gltf, buffers: &[Vec<u8>]) -> std::result::Result<(), String> {
    for v in doc.views() {
        let len = buffers.get(v.buffer().index()).map_or(0, Vec::len);
        let end = v.offset().checked_add(v.length());
        if end.is_none_or(|e| e > len) {
            return Err(format!(
                "buffer view {} ({} bytes at {}) runs past its buffer's {} bytes",
                v.index(),
                v.length(),
                v.offset(),
                len
            ));
        }
    }
    Ok(())
}

/// `accessor` inside its view: the last element's bytes end within the view.
fn check_accessor(a: &gltf::Accessor<'_>, what: &str) -> std::result::Result<(), String> {
    if a.sparse().is_some() {
        return Err(format!("sparse {what} accessors are not supported"));
    }
    let Some(view) = a.view() else {
        return Err(format!("the {what} accessor has no buffer view"));
    };
    let size = a.size();
    let stride = view.stride().unwrap_or(size);
    let need = match a.count() {
        // glTF requires count >= 1 (and the crate's reader underflows on 0).
        0 => return Err(format!("the {what} accessor has no elements")),
        n => (n - 1)
            .checked_mul(stride)
            .and_then(|x| x.checked_add(size))
            .and_then(|x| x.checked_add(a.offset())),
    };
    if need.is_none_or(|n| n > view.length()) {
        return Err(format!(
            "the {what} accessor ({} elements of {size} bytes, stride {stride}, at {}) runs past its view's {} bytes",
            a.count(),
            a.offset(),
            view.length()
        ));
    }
    Ok(())
}

/// Appends one triangle primitive's triangles, in world space, to `out`.
fn read_primitive(
    prim: &gltf::Primitive<'_>,
    buffers: &[Vec<u8>],
    world: Mat4,
    out: &mut Vec<[Vec3; 3]>,
) -> std::result::Result<(), String> {
    let pos = prim
        .get(&gltf::Semantic::Positions)
        .ok_or("no POSITION attribute")?;
    check_accessor(&pos, "POSITION")?;
    if pos.dimensions() != Dimensions::Vec3 || pos.data_type() != DataType::F32 {
        return Err(format!(
            "POSITION is {:?} of {:?}; glTF requires VEC3 of FLOAT",
            pos.dimensions(),
            pos.data_type()
        ));
    }
    if let Some(ix) = prim.indices() {
        check_accessor(&ix, "index")?;
        let int = matches!(ix.data_type(), DataType::U8 | DataType::U16 | DataType::U32);
        if ix.dimensions() != Dimensions::Scalar || !int {
            return Err(format!(
                "indices are {:?} of {:?}; glTF requires SCALAR of UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT",
                ix.dimensions(),
                ix.data_type()
            ));
        }
    }
    let reader = prim.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
    let positions: Vec<Vec3> = reader
        .read_positions()
        .ok_or("POSITION cannot be read")?
        .map(|p| world.transform_point3(Vec3::from_array(p)))
        .collect();
    if let Some(k) = positions.iter().position(|p| !p.is_finite()) {
        return Err(format!("position {k} is not finite"));
    }
    let indices: Vec<u32> = match reader.read_indices() {
        Some(ix) => ix.into_u32().collect(),
        None => (0..positions.len() as u32).collect(),
    };
    if !indices.len().is_multiple_of(3) {
        return Err(format!("{} indices, not a multiple of 3", indices.len()));
    }
    for t in indices.chunks_exact(3) {
        let mut tri = [Vec3::ZERO; 3];
        for (c, &i) in tri.iter_mut().zip(t) {
            *c = *positions
                .get(i as usize)
                .ok_or_else(|| format!("index {i} past the {} positions", positions.len()))?;
        }
        out.push(tri);
    }
    Ok(())
}

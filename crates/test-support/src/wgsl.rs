//! WGSL checks without a device (naga): every crate's shader unit tests validate its shaders and
//! the WGSL mirrors of its `#[repr(C)]` structs here, so a WGSL error fails CPU-only CI.

/// Parses and validates `src` with naga, or returns the error rendered against the source,
/// prefixed with `name`.
pub fn validate_wgsl(name: &str, src: &str) -> Result<naga::Module, String> {
    let module = naga::front::wgsl::parse_str(src)
        .map_err(|e| format!("{name}: {}", e.emit_to_string(src)))?;
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .map_err(|e| format!("{name}: {}", e.emit_to_string(src)))?;
    Ok(module)
}

/// Panics naming every shader of `shaders` (`(name, complete source)`) that naga does not parse
/// and validate ([`validate_wgsl`]).
pub fn assert_shaders_valid<'a, S: AsRef<str>>(shaders: impl IntoIterator<Item = (&'a str, S)>) {
    let errors: Vec<String> = shaders
        .into_iter()
        .filter_map(|(name, src)| validate_wgsl(name, src.as_ref()).err())
        .collect();
    assert!(errors.is_empty(), "{}", errors.join("\n"));
}

/// The value of the WGSL `const NAME: u32 = <literal>;` in `src` (validated with naga), for a
/// test that ties a Rust constant to the WGSL one it must equal; an error naming what is missing.
pub fn u32_constant(src: &str, name: &str) -> Result<u32, String> {
    let module = validate_wgsl(name, src)?;
    let (_, c) = module
        .constants
        .iter()
        .find(|(_, c)| c.name.as_deref() == Some(name))
        .ok_or_else(|| format!("no const `{name}` in the WGSL"))?;
    match module.global_expressions[c.init] {
        naga::Expression::Literal(naga::Literal::U32(v)) => Ok(v),
        ref e => Err(format!("const `{name}` is {e:?}, not a u32 literal")),
    }
}

/// Checks a `#[repr(C)]` Rust mirror of a WGSL struct: `fields` are the Rust side's `(name,
/// byte offset)` in declaration order (padding arrays spelled out as the WGSL names them) and
/// `size` its `size_of`; the WGSL struct `name` in `src` must have the same member names at the
/// same offsets and the same size. Returns what differs, in one line.
pub fn check_struct_layout<S: AsRef<str>>(
    src: &str,
    name: &str,
    size: usize,
    fields: &[(S, usize)],
) -> Result<(), String> {
    let module = validate_wgsl(name, src)?;
    let ty = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .map(|(_, t)| t)
        .ok_or_else(|| format!("struct {name} is not in the WGSL"))?;
    let naga::TypeInner::Struct { members, span } = &ty.inner else {
        return Err(format!("{name} is not a struct in the WGSL"));
    };
    let wgsl: Vec<(String, usize)> = members
        .iter()
        .map(|m| (m.name.clone().unwrap_or_default(), m.offset as usize))
        .collect();
    let rust: Vec<(String, usize)> = fields
        .iter()
        .map(|(n, o)| (n.as_ref().to_string(), *o))
        .collect();
    if wgsl != rust {
        return Err(format!(
            "{name}: WGSL members {wgsl:?} differ from the Rust mirror {rust:?}"
        ));
    }
    if *span as usize != size {
        return Err(format!(
            "{name}: WGSL size {span} differs from the Rust size {size}"
        ));
    }
    Ok(())
}

/// Asserts that a `#[repr(C)]` Rust struct and its WGSL mirror agree member by member (names and
/// offsets, with [`check_struct_layout`]) and in size: `assert_wgsl_layout!(src, Ty { a, b, c })`,
/// with `, pad _pad: 3` when a trailing `_pad: [u32; 3]` is spelled `_pad0.._pad2` in the WGSL.
#[macro_export]
macro_rules! assert_wgsl_layout {
    ($src:expr, $ty:ident { $($field:ident),* $(,)? } $(, pad $pad:ident : $n:literal)?) => {{
        #[allow(unused_mut)]
        let mut fields: Vec<(String, usize)> = vec![
            $((stringify!($field).to_string(), std::mem::offset_of!($ty, $field))),*
        ];
        $(
            for i in 0..$n {
                fields.push((
                    format!("{}{}", stringify!($pad), i),
                    std::mem::offset_of!($ty, $pad) + 4 * i,
                ));
            }
        )?
        if let Err(e) = $crate::wgsl::check_struct_layout(
            &$src,
            stringify!($ty),
            std::mem::size_of::<$ty>(),
            &fields,
        ) {
            panic!("{e}");
        }
    }};
}

//! The examples' command line: `--flag value` pairs and value-less switches.

/// The command-line arguments as `(flag, value)` pairs: a flag in `switches` takes no value
/// (`""`), any other flag the argument after it.
pub fn flags(switches: &[&str]) -> Vec<(String, String)> {
    let mut args = std::env::args().skip(1);
    let mut out = Vec::new();
    while let Some(flag) = args.next() {
        let value = if switches.contains(&flag.as_str()) {
            String::new()
        } else {
            args.next().unwrap_or_default()
        };
        out.push((flag, value));
    }
    out
}

/// A `WxH` size.
pub fn size(s: &str) -> (u32, u32) {
    let p: Vec<u32> = s.split('x').filter_map(|x| x.trim().parse().ok()).collect();
    (p[0], p[1])
}

//! Per-pixel diagnostics of packet-hsm as an OpenEXR image (Yang Figs. 5 and 8): channels `V`,
//! `Z` (the contract's), `kernel` (largest kernel side in dual cells over the sub-lights),
//! `visited` (MSSM nodes or 2x2 blocks visited, a packet's visits shared by its pixels) and
//! `packet` (0: fully lit / umbra / no map work, 1: coherent packet, 2: pixel-wise).
//!
//! ```text
//! cargo run --release -p packet-hsm --example diagnostics -- FIXTURE OUT.exr [KEY=VALUE ...]
//! ```
//! e.g. `-- bunny /tmp/bunny-diag.exr packet=4x4 resolution=512`.
use exr::prelude::{AnyChannel, AnyChannels, FlatSamples, Image, SmallVec, Text, WritableImage};
use packet_hsm::CpuPacketHsm;
use shadow_map_core::{run, Receivers, Scene, SceneBvh, SoftShadowEstimator};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(name), Some(out)) = (args.first(), args.get(1)) else {
        return Err("usage: diagnostics FIXTURE OUT.exr [KEY=VALUE ...]".into());
    };
    let path = format!(
        "{}/../../fixtures/{name}/{name}.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let scene = Scene::load(&path)?;
    let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
    let mut e = CpuPacketHsm::new()?;
    for kv in &args[2..] {
        let (k, v) = kv.split_once('=').ok_or("parameters are KEY=VALUE")?;
        e.set_param(k, v)?;
    }
    let (v, report) = run(&mut e, &scene, &rec)?;
    let d = e.diagnostics();
    let z = rec
        .view_depth()
        .map_or_else(|| vec![f32::INFINITY; rec.len()], <[f32]>::to_vec);
    let chan =
        |n: &str, data: Vec<f32>| AnyChannel::new(Text::new_or_panic(n), FlatSamples::F32(data));
    let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    list.push(chan("V", v));
    list.push(chan("Z", z));
    list.push(chan("kernel", d.iter().map(|p| p.kernel).collect()));
    list.push(chan("visited", d.iter().map(|p| p.visited).collect()));
    list.push(chan("packet", d.iter().map(|p| p.class as f32).collect()));
    let size = (
        scene.camera().width as usize,
        scene.camera().height as usize,
    );
    let image = Image::from_channels(size, AnyChannels::sort(list));
    image.write().to_file(out)?;
    println!("wrote {out}; {:?}", report.notes);
    Ok(())
}

//! Reading an OpenEXR file's first layer whole: every channel, flat samples, every attribute.
//! The CLI's reader ([`super::read_exr`]) and the integration tests that check the files the
//! CLI wrote share this one file (the tests include it by path: the CLI has no library).

use exr::prelude::{AnyChannels, FlatSamples, Image, Layer, ReadChannels, ReadLayers};
use std::path::Path;

/// An EXR image of one layer: every channel's samples, the header's and the layer's attributes.
pub type FirstLayer = Image<Layer<AnyChannels<FlatSamples>>>;

/// The first valid layer of the OpenEXR file at `path` at its largest resolution, every channel
/// and attribute; deep data is refused (an error, as is an unreadable file).
pub fn read_first_layer(path: &Path) -> exr::error::Result<FirstLayer> {
    exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
}

// Reading an active list (compact.wgsl, receivers::ActiveLists) bound as `active_list: array<u32>`
// by the including kernel, dispatched indirectly from its head: invocation i of the dispatch
// estimates receiver active_list[4 + i] of the range, for i < active_list[3].

const NONE_LISTED: u32 = 0xffffffffu;

// The receiver of invocation i, or NONE_LISTED past the list's end (the last workgroup's spare
// invocations).
fn listed_receiver(i: u32) -> u32 {
    if i >= active_list[3] {
        return NONE_LISTED;
    }
    return active_list[4u + i];
}

// The receiver of workgroup wid of a dispatch of one workgroup per listed receiver (a list kind
// made for it, compact.wgsl's PER_RECEIVER_GROUP), or NONE_LISTED past the list's end.
fn listed_receiver_of_group(wid: vec3<u32>) -> u32 {
    return listed_receiver(wid.x + wid.y * 65535u);
}

// The constants Rust and GLSL share, in one list. `src/gpu.rs` turns it into
// `pub const`s; build.rs turns the same file into `constants.glsl` (included
// by glsl/shared.glsl), so a value is written once. Only `u32`, `i32` and
// `f32` constants; a doc comment travels to both sides.
gpu_constants! {
    /// Rows of one band job: large footprints are cut into bands this high.
    BAND_ROWS: u32 = 8;
    /// Most workgroups along x of one dispatch; larger grids fold into y.
    MAX_GROUPS_X: u32 = 65535;
    /// Deep lists: tile side in texels (one 64-invocation workgroup).
    DEEP_TILE: u32 = 8;
    /// Deep lists: entries per chunk.
    DEEP_CHUNK: u32 = 64;
    /// Deep lists: list terminator / "no chunk".
    DEEP_NONE: u32 = 0xFFFF_FFFF;
    /// Deep lists: tile flag, the tile did not fit in the pool.
    DEEP_TILE_OVERFLOWED: u32 = 1;
    /// Deep counters: chunks requested from the pool (may exceed capacity).
    C_CHUNKS: u32 = 0;
    /// Deep counters: 1 if a tile did not fit.
    C_OVERFLOW: u32 = 1;
    /// Deep counters: entries counted.
    C_ENTRIES: u32 = 2;
    /// Deep counters: largest entry count of a texel (depth complexity).
    C_MAX_COUNT: u32 = 3;
    /// Deep counters: compressed visibility nodes, all texels.
    C_NODES: u32 = 4;
    /// Deep counters: fill slots outside their texel's run (must stay 0).
    C_FILL_ERRORS: u32 = 5;
    /// Deep counters: most compressed nodes of a texel.
    C_MAX_NODES: u32 = 6;
    /// Deep counters: texels with at least one entry.
    C_NONEMPTY: u32 = 7;
    /// Deep counters: entries of overflowed tiles (not stored).
    C_DROPPED: u32 = 8;
    /// Deep counters: texels whose sort and walk a loop limit cut short
    /// (lavapipe ends a shader invocation's loops after 65,535 back-edges,
    /// CULL_CHUNK_BATCHES; a run of thousands of entries reaches it).
    C_SORT_CUT: u32 = 9;
    /// The largest footprint (texels) a per-sphere invocation visits
    /// itself where the job list is full and stays within lavapipe's
    /// 65,535 loop back-edges with room for its other loops (the deep
    /// lists' and see-through fragments' count and fill passes; past it
    /// they flag the frame, drawn again with a longer list).
    BAND_INLINE_SAFE: u32 = 32768;
    /// Deep counters: set where a sphere's bands did not fit the job list
    /// and its own invocation counted more than BAND_INLINE_SAFE texels:
    /// the frame is drawn again with a longer list.
    C_BANDS_FULL: u32 = 10;
    /// Deep counters: band jobs requested.
    C_BANDS_REQ: u32 = 16;
    /// Deep counters: band jobs dispatched.
    C_BANDS_RUN: u32 = 17;
    /// Deep counters: first of the three indirect dispatch words.
    C_ARGS: u32 = 20;
    /// See-through fragment lists: "no list" (an empty pixel, or one of a
    /// tile that did not fit in the pool).
    F_NONE: u32 = 0xFFFF_FFFF;
    /// Fragment counters: fragments requested from the pool (may exceed
    /// its capacity: then what the frame needs).
    F_TOTAL: u32 = 0;
    /// Fragment counters: 1 if a tile did not fit.
    F_OVERFLOW: u32 = 1;
    /// Fragment counters: most fragments of a pixel.
    F_MAX: u32 = 2;
    /// Fragment counters: fill slots outside their pixel's run (must stay 0).
    F_FILL_ERRORS: u32 = 3;
    /// Fragment counters: pixels with a fragment.
    F_PIXELS: u32 = 4;
    /// Fragment counters: pixels whose composite (shade.comp) a loop limit
    /// cut short (lavapipe ends a shader invocation's loops after 65,535
    /// back-edges: thousands of faint fragments in one pixel reach it).
    F_COMPOSITE_CUT: u32 = 5;
    /// Fragment counters: band jobs requested, dispatched, and the first
    /// of the three indirect dispatch words.
    F_BANDS_REQ: u32 = 16;
    /// Fragment counters: set where a sphere's bands did not fit the job
    /// list and its own invocation visited more than BAND_INLINE_SAFE
    /// texels: the frame is drawn again with a longer list.
    F_BANDS_FULL: u32 = 6;
    F_BANDS_RUN: u32 = 17;
    F_ARGS: u32 = 20;
    /// Fragment counters: 1 if a sphere's own invocation visited its
    /// footprint (its inline bit set): the bits are cleared before the
    /// next frame (only then: a frame's ids span the LOD lists' slots,
    /// tens of MB of bits at meso 10^9).
    F_INLINED: u32 = 9;
    /// Fragment counters (a frame that draws the LOD lists): the camera's
    /// listed batches picked for the fragments (glsl/oit_pick.comp), and
    /// the first of their three indirect dispatch words.
    F_PICKED: u32 = 8;
    F_PICK_ARGS: u32 = 24;
    /// Raster counters: band jobs requested.
    R_BANDS_REQ: u32 = 0;
    /// Raster counters: band jobs dispatched.
    R_BANDS_RUN: u32 = 1;
    /// Raster counters: first of the three indirect dispatch words.
    R_ARGS: u32 = 4;
    /// Raster counters: set where a sphere's bands did not fit the job
    /// list (its own invocation drew it); kept over the frame's passes,
    /// read and cleared after it (the frame is drawn again, the list
    /// longer).
    R_BANDS_FULL: u32 = 8;
    /// SSDO block side in pixels: SSDO runs on one representative pixel per
    /// SSDO_BLOCK x SSDO_BLOCK block.
    SSDO_BLOCK: u32 = 2;
    /// Per-sphere SSDO (spheres a few pixels wide): directions per sphere,
    /// SSDO_SPHERE_AZIMUTHS screen-space lines x the elevations that share
    /// each line's taps.
    SSDO_SPHERE_DIRS: u32 = 32;
    SSDO_SPHERE_AZIMUTHS: u32 = 8;
    /// Per-sphere SSDO counters: spheres listed, their workgroups, and the
    /// band_args words (run, then the three indirect dispatch words).
    S_LISTED: u32 = 0;
    S_GROUPS: u32 = 1;
    S_RUN: u32 = 2;
    S_ARGS: u32 = 3;
    /// Tile lists (coverage.comp): 16x16-pixel regions (8x8 SSDO blocks)
    /// that show a sphere and those that do not. Words: the two counts,
    /// four indirect dispatch triples from TL_ARGS (full-resolution 8x8
    /// tiles of the covered regions, of the background ones, then the
    /// regions themselves as half-resolution tiles, covered, background),
    /// then one packed region (x | y << 16) per region from TL_LIST:
    /// covered ones from the front, background ones from the back.
    TL_COVERED: u32 = 0;
    TL_BACKGROUND: u32 = 1;
    TL_ARGS: u32 = 4;
    TL_LIST: u32 = 16;
    /// Region side in pixels.
    TL_REGION: u32 = 16;
    /// Deep lists: light-space disk enlargement in texels (conservative
    /// footprints: a missed texel would leak light, an extra entry costs one
    /// exact ray test).
    DEEP_DISK_SLACK: f32 = 0.01;
    /// ISSM resolved map (issm_resolve.comp): the light-space x and y of an
    /// empty texel, so far from every point that no test hits it.
    ISSM_EMPTY_XY: f32 = 1e30;
    /// Scene kinds (the low byte of specialization constant SCENE_SPEC,
    /// id SCENE_KIND_ID): plain spheres; instances with rigid (quaternion)
    /// transforms; with affine (3x4 as stored) transforms. Its next byte is
    /// an instanced scene's batch shift: a sphere id is a slot, batch
    /// `id >> shift`, atom `id & (2^shift - 1)` of the batch's run of one
    /// instance's molecule (glsl/scene.glsl).
    SCENE_PLAIN: u32 = 0;
    SCENE_RIGID: u32 = 1;
    SCENE_AFFINE: u32 = 2;
    SCENE_KIND_ID: u32 = 30;
    /// Batch shifts an instanced scene may use (8 to 64 slots a batch).
    MIN_BATCH_SHIFT: u32 = 3;
    MAX_BATCH_SHIFT: u32 = 6;
    /// A batch's record's last word (glsl/scene.glsl `scene_batch`): atom
    /// count (bits 0-7) | molecule type << 8 (types below 2^23) |
    /// BATCH_COARSE, set on a batch of a coarse level of detail, whose
    /// lanes name their atoms through originTex (`scene_index`).
    BATCH_COARSE: u32 = 0x8000_0000;
    BATCH_TYPE_MASK: u32 = 0x7F_FFFF;
    /// A batch as stored (batchTex, 8 bytes): its instance (the low
    /// BATCH_INSTANCE_BITS bits: the most instances a scene holds) | its
    /// level of detail << BATCH_INSTANCE_BITS, then its index among that
    /// level's batches; BATCH_EMPTY names the empty batch (no atoms).
    BATCH_INSTANCE_BITS: u32 = 24;
    BATCH_INSTANCE_MASK: u32 = 0xFF_FFFF;
    BATCH_EMPTY: u32 = 0xFF00_0000;
    /// Levels of detail a molecule type may have (src/scene/instanced/lod.rs
    /// `strides` reaches one sphere within them up to 2^30 atoms).
    MAX_LOD_LEVELS: u32 = 16;
    /// A level row's first word (levelTex .x: level 0's holds the number
    /// of levels) has LEVEL_MAPPED set on every level of a nested scene's
    /// proxy molecule type: its lanes name their atoms through originTex at
    /// level 0 too (src/scene/instanced/nested.rs).
    LEVEL_MAPPED: u32 = 0x8000_0000;
    LEVEL_COUNT_MASK: u32 = 0xFFFF;
    /// Counter words per list of the LOD cull (glsl/lod_cull.comp): batches
    /// listed, spheres drawn, then the three indirect dispatch words; lists
    /// camera (early), light (early), camera (late), light (late). An early
    /// list's words then count what its view's early phase deferred to the
    /// late one (instances, batches) and hold the late phase's two
    /// dispatches' arguments; the camera's early list's also whether its
    /// early depth tiles differ from last frame's final ones and the
    /// arguments of its recheck (CAM_RECHECK).
    LOD_WORDS: u32 = 20;
    LOD_VIEWS: u32 = 4;
    /// RasterPush.list_base of a view drawn in its order (not a LOD list).
    RASTER_ORDER: u32 = 0xFFFF_FFFF;
    /// Entries after each LOD list's capacity, empty: the last
    /// workgroup's lanes read past the count.
    LOD_LIST_TAIL: u32 = 64;
    /// A level coarser than last frame's is taken only below its switch
    /// size divided by this (glsl/lod_cull.comp).
    LOD_BAND: f32 = 1.15;
    /// The occlusion test's depth tiles (glsl/lod_hiz.comp): fine ones of
    /// 2^s pixels a side, s the least from HIZ_MIN_SHIFT that keeps a
    /// view's within HIZ_FINE_TILES (4 px at 1080p and on a 4096^2 light
    /// map; 16 px on a 16384^2 window), then coarse ones of 8x8 fine.
    HIZ_MIN_SHIFT: u32 = 2;
    /// The light's receiver depths in the LOD region buffer: from this
    /// word (after x0, y0, x1, y1), a depth word per receiver tile
    /// (glsl/lod_receivers.glsl).
    LOD_RECEIVERS_AT: i32 = 4;
    /// The most depth tiles a side a light depth tile's lookup window may
    /// span for its receivers to be read (glsl/lod_hiz.comp): (2 x 90 +
    /// 1)^2 loads stay within lavapipe's loop limit.
    RECEIVER_WINDOW: i32 = 181;
    HIZ_FINE_TILES: u32 = 1048576;
    /// Level-0 batches one invocation of the LOD cull tests (an instance
    /// of more is taken in chunks, each by its own invocation): lavapipe
    /// (Mesa 22.3's gallivm) ends every loop of a shader invocation once
    /// its loops together took 65,535 back-edges (LP_MAX_TGSI_LOOP_ITERATIONS,
    /// counted over the 8 lanes run together), silently; a batch costs at
    /// most 1 + 2 x (8 x 8 + 8) of them (glsl/lod_cull.comp `hidden`),
    /// 256 batches 37 k. (A 1,391-batch capsid protein of the 10^12 scene
    /// stopped after 821-1,391 batches, by its lanes' neighbours: the
    /// light's list and shadows changed run to run.)
    CULL_CHUNK_BATCHES: u32 = 256;
    /// The cull's per-instance level before any frame chose one.
    NO_LEVEL_YET: u32 = 0xFFFF_FFFF;
    LOD_BATCHES: u32 = 0;
    LOD_SPHERES: u32 = 1;
    LOD_ARGS: u32 = 2;
    LOD_DEFER_INSTANCES: u32 = 5;
    LOD_DEFER_BATCHES: u32 = 6;
    LOD_DEFER_INSTANCE_ARGS: u32 = 7;
    LOD_DEFER_BATCH_ARGS: u32 = 10;
    /// A list's indirect dispatch arguments with one invocation per batch
    /// (the light's batch raster, glsl/raster.comp LIGHT_BATCHES).
    LOD_BATCH_ARGS: u32 = 13;
    /// (the camera's words) Non-zero when a fine depth tile of its early
    /// image differs from last frame's final one (glsl/lod_hiz.comp);
    /// else no atom of the early list can pass the recheck, whose
    /// arguments (LOD_RECHECK_ARGS, glsl/lod_args.comp) are then empty.
    LOD_TILES_CHANGED: u32 = 16;
    LOD_RECHECK_ARGS: u32 = 17;
    /// An instance's flags in the LOD cull's visibility arrays: it passed
    /// the occlusion test; the camera's final image shows it (written in
    /// a moved camera's frames, glsl/lod_shown.comp).
    VISIBLE_PASSED: u32 = 1;
    VISIBLE_SHOWN: u32 = 2;
    /// Slots of a batch one invocation of a per-batch raster (the light's,
    /// the camera's) takes (fewer for smaller batches): its loops' bound
    /// (glsl/raster.comp `batch_part`).
    BATCH_PART_SLOTS: u32 = 32;
    /// The camera's LOD lists per batch (specialization constant 5 of
    /// glsl/raster.comp): each atom projected and tested against depth
    /// tiles before it is drawn. CAM_EARLY: the early list, atoms that
    /// last frame's final tiles do not hide; CAM_RECHECK: the early list
    /// again, atoms those tiles hid that this frame's early tiles do not;
    /// CAM_LATE: the late list, atoms this frame's early tiles do not hide.
    CAM_PER_SLOT: u32 = 0;
    CAM_EARLY: u32 = 1;
    CAM_RECHECK: u32 = 2;
    CAM_LATE: u32 = 3;
    /// The LOD cull's passes (specialization constant 2 of
    /// glsl/lod_cull.comp): an early phase over every instance, a late one
    /// over the instances the early one deferred, a late one over the
    /// batches it deferred.
    CULL_EARLY: u32 = 0;
    CULL_DEFERRED_INSTANCES: u32 = 1;
    CULL_DEFERRED_BATCHES: u32 = 2;
    /// Globals.scene.zw: no molecule / chain level.
    NO_LEVEL: u32 = 0xFFFF_FFFF;
}

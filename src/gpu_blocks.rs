// The push-constant blocks and specialization constants Rust and GLSL
// share, each written once. `src/gpu.rs` turns this file into Rust structs
// (`gpu_push!`: #[repr(C)] Pod structs; `gpu_spec!`: a struct whose
// `constants()` lists its fields as specialization constants 1, 2, ... in
// declaration order); build.rs turns the same file into GLSL includes
// (`#include "push/NAME.glsl"`, `#include "spec/NAME.glsl"`), so that the
// order, types and size of a block cannot drift between the two sides. A
// doc comment travels to both. Field types: `u32`, `i32`, `f32`, `bool`
// (spec only), `[u32; N]` (push padding), `GpuView` (push only: the
// shader has shared.glsl's `View`) and a `gpu_knobs!` struct (a
// GLSL struct of scalars, `#include "knobs/NAME.glsl"`: knob structs are
// also clap arguments, so a knob is written once). A spec include also defines
// SPEC_NEXT_ID, the id after its last constant (a tiled shader's
// TILE_LIST_ID).

gpu_knobs! {
    /// The shading knobs that reach `shade` as they are: flattened into the
    /// command line (through `Look`), copied whole into `ShadePush::knobs`.
    /// A new one is its field here and the shader line that reads
    /// `pc.knobs.NAME`.
    ShadeKnobs "shade_knobs" {
        /// Fraction of the key light's diffuse term kept in full shadow (the
        /// ISSM paper's rule: a shadowed point keeps its ambient light and
        /// this much of the key's diffuse term, and loses its specular).
        #[arg(long, default_value_t = 0.05, allow_negative_numbers = true, value_parser = crate::gpu::unit_interval)]
        shadow_diffuse: f32,
    }
}

gpu_push! {
    /// `shade` (glsl/shade.comp).
    ShadePush "shade" {
        /// The knobs the shader reads as they are.
        knobs: ShadeKnobs,
        /// Silhouette line width in pixels (with OUTLINE).
        outline_px: f32,
        /// Depth cue from view_z fog_near to fog_far (read with FOG, which
        /// the host sets when far > near).
        fog_near: f32,
        fog_far: f32,
        /// A neighbour nearer by more than this (world units) makes a line.
        edge_dz: f32,
        /// Hierarchy level whose region changes make lines.
        level: u32,
        /// Depth tolerance (world units) of the SSDO upsample.
        ao_sigma_z: f32,
        /// 1: the upsample compares regions at the records' level b, 0: level a.
        ao_level_b: u32,
    }

    /// `ssdo` and per-sphere `ssdo` (glsl/ssdo.comp, glsl/ssdo_sphere.comp).
    SsdoPush "ssdo" {
        /// Near sample radius (world units).
        r_near: f32,
        /// Far search radius (world units).
        r_far: f32,
        /// Weight of level b in the region test.
        blend: f32,
        /// Bounce strength.
        bounce: f32,
        level_a: u32,
        level_b: u32,
        /// The per-pixel blur compares regions at level b (else a): the keys'.
        blur_level_b: u32,
        pad: u32,
    }

    /// `ssdo_prep` (glsl/ssdo_prep.comp).
    PrepPush "ssdo_prep" {
        level_a: u32,
        level_b: u32,
        pad: [u32; 2],
    }

    /// The per-sphere SSDO list (glsl/ssdo_list.comp).
    ListPush "ssdo_list" {
        /// Flag words, one bit per sphere: ceil(sphere_count / 32).
        words: u32,
        /// log2 of ssdo_sphere.comp's workgroup size (groups counted by shifts).
        group_shift: u32,
        /// Entries the list (and the results) hold: the buffer's pixels at
        /// most, since every listed sphere is seen in one.
        capacity: u32,
        pad: u32,
    }

    /// `blur_h`, `blur_v` (glsl/blur.comp).
    BlurPush "blur" {
        /// Depth tolerance (world units).
        sigma_z: f32,
        /// Half resolution: 1 = the region test compares the records' level-b
        /// regions, 0 = level a (per pixel, the keys hold the right one).
        level_b: u32,
        pad: [u32; 2],
    }

    /// The compute rasterizer (glsl/raster.comp).
    RasterPush "raster" {
        /// 0 camera, 1 key light.
        view_index: u32,
        /// Footprints larger than this (pixels) go to band jobs.
        big_area: u32,
        /// Entries of the band job buffer.
        job_capacity: u32,
        sphere_count: u32,
        /// A LOD list's first batch in the scene's batch table (the lists,
        /// glsl/lod_cull.comp): invocation i draws slot
        /// (list_base << shift) + i; RASTER_ORDER: the view's order.
        list_base: u32,
        /// The camera's depth tiles' shift (fine tiles of 2^s pixels,
        /// glsl/lod_hiz.comp), for its per-batch tests (CAM_EARLY, ...).
        hiz_shift: u32,
        /// Where the camera's 2-px tiles start in its tile buffers (0:
        /// none; src/stages/raster/lod.rs `micro_base`).
        micro_base: u32,
        pad: u32,
        /// The view the camera's last final tiles were made in, where its
        /// early and recheck tests place each atom (LodCullPush.prev).
        prev: GpuView,
    }

    /// `lod_cull` (glsl/lod_cull.comp): one invocation per instance.
    LodCullPush "lod_cull" {
        /// (the view and phase are the pipeline's specialization
        /// constants VIEW and MODE)
        instances: u32,
        /// Entries of the view's batch list.
        capacity: u32,
        /// The late phases' fine depth tiles are 2^hiz_shift pixels a side
        /// (`hiz_shift`, src/stages/raster/lod.rs).
        hiz_shift: u32,
        /// Light views: the farthest (texels) the shadow lookup reads from
        /// the texel its point projects to (`Lookup::reach`).
        reach: i32,
        /// Batch entries the early phase may defer to the late one (after
        /// one entry per instance in the deferral buffer).
        deferred: u32,
        /// Further chunks of large instances the early phase takes after
        /// the instances (src/passes/scene.rs `cull_chunks`).
        chunks: u32,
        /// Which of the two per-instance visibility arrays holds last
        /// frame's (the other is this frame's).
        parity: u32,
        /// The flags of last frame's visibility array the early phase
        /// lists instances by: VISIBLE_PASSED, or after a camera's small
        /// move VISIBLE_SHOWN (src/stages/raster/lod.rs `small_move`).
        history: u32,
        /// The view last frame's final depth tiles (`hizPrevTex`) were
        /// made in: the early phase places what it tests there (a moved
        /// view tests what last frame's image hid, not where it is now).
        /// 128 bytes in all, Vulkan's least maxPushConstantsSize.
        prev: GpuView,
    }

    /// `lod_front` (glsl/lod_front.comp).
    LodFrontPush "lod_front" {
        instances: u32,
        /// LodCullPush.parity (the early phase reads this array's flags).
        parity: u32,
        /// Cells of 2^cell_shift pixels a side.
        cell_shift: u32,
        pad: u32,
    }

    /// `lod_shown` (glsl/lod_shown.comp).
    LodShownPush "lod_shown" {
        /// Slots per LOD batch: 2^batch_shift.
        batch_shift: u32,
        /// LodCullPush.parity (this frame's visibility array is the other).
        parity: u32,
        instances: u32,
        pad: u32,
    }

    /// `lod_bounds` (glsl/lod_bounds.comp).
    LodBoundsPush "lod_bounds" {
        /// The light map's receiver tiles are 2^hiz_shift texels a side
        /// (src/stages/raster/lod.rs `receiver_shift`).
        hiz_shift: u32,
        /// World units a caster may lie behind a point and still darken
        /// it (`Lookup::depth_slack`).
        slack: f32,
        pad: [u32; 2],
    }

    /// `lod_hiz` (glsl/lod_hiz.comp).
    LodHizPush "lod_hiz" {
        /// 0 camera, 1 key light.
        view_index: u32,
        /// Fine tiles of 2^hiz_shift pixels a side.
        hiz_shift: u32,
        /// The light: the lookup's reach (texels, `Lookup::reach`).
        reach: i32,
        /// The light: its receiver tiles are 2^receiver_shift texels a
        /// side (src/stages/raster/lod.rs `receiver_shift`).
        receiver_shift: u32,
        /// The camera's early tiles: flag LOD_TILES_CHANGED where a fine
        /// tile differs from last frame's (hizPrevTex).
        compare: u32,
        /// The camera's 4-px fine tiles: its 2-px tiles too, from this
        /// word (0: none; src/stages/raster/lod.rs `micro_base`).
        micro_base: u32,
        pad: [u32; 2],
    }

    /// `lod_args` (glsl/lod_args.comp): the cull's counts into indirect
    /// dispatch arguments.
    LodArgsPush "lod_args" {
        /// Slots per batch (2^shift).
        per: u32,
        /// Entries of a view's batch list.
        capacity: u32,
        /// Invocations per workgroup of the rasterizer.
        local_size: u32,
        /// Batch entries the early phases may defer (LodCullPush.deferred).
        deferred: u32,
    }

    /// A band sequence's counter words (glsl/band_args.comp): where they
    /// live in the pass's counter buffer.
    BandCounters "band_args" {
        /// Most band jobs the job buffer holds.
        job_capacity: u32,
        /// Word the per-sphere pass counts requested bands in.
        requested: u32,
        /// Word that receives the number of bands that run.
        run: u32,
        /// First of the three indirect dispatch words.
        args: u32,
    }

    /// `deep_count` and `deep_fill` (glsl/deep_splat.comp).
    SplatPush "deep_splat" {
        sphere_count: u32,
        /// Footprints above this many texels go to band jobs.
        big_area: u32,
        /// Entries of the band job buffer.
        job_capacity: u32,
        /// Entries of the list arrays (pool chunks * 64).
        entry_capacity: u32,
    }

    /// `oit_count` and `oit_fill` (glsl/oit_splat.comp).
    OitSplatPush "oit_splat" {
        sphere_count: u32,
        /// Footprints above this many pixels go to band jobs.
        big_area: u32,
        /// Entries of the band job buffer.
        job_capacity: u32,
        /// Fragments the pool holds.
        capacity: u32,
        /// Per batch (BATCHES): the final image's depth tiles (`hizTex`),
        /// fine tiles of 2^hiz_shift pixels, 2-px ones from micro_base.
        hiz_shift: u32,
        micro_base: u32,
        /// 1: the count adds the key light's receivers of its fragments
        /// (`Region`, lod_bounds.comp's words; receiver tiles of
        /// 2^receiver_shift texels; the lookup's depth slack).
        receivers: u32,
        receiver_shift: u32,
        slack: f32,
    }

    /// `oit_pick` (glsl/oit_pick.comp): the see-through batches of the
    /// camera's LOD lists.
    OitPickPush "oit_pick" {
        /// MODE 1: the list's first entry; its count's word in the LOD
        /// counters.
        list_base: u32,
        list_word: u32,
        /// MODE 0: stored atoms; MODE 1: the most entries the list holds.
        capacity: u32,
        /// Entries the picked list holds.
        room: u32,
        /// MODE 2: the splat's invocations per picked batch (its slots,
        /// or its parts where it runs per batch).
        per_batch: u32,
    }

    /// `oit_alloc` (glsl/oit_alloc.comp).
    OitAllocPush "oit_alloc" {
        /// Fragments the pool holds.
        capacity: u32,
    }

    /// `deep_alloc` (glsl/deep_alloc.comp).
    AllocPush "deep_alloc" {
        /// Chunks in the pool.
        chunk_capacity: u32,
    }

    /// `deep_sort` (glsl/deep_sort.comp).
    SortPush "deep_sort" {
        /// Compression tolerance on V.
        eps: f32,
        /// Entries of the list arrays.
        entry_capacity: u32,
    }

    /// `osm_raster` (glsl/osm_raster.comp).
    OsmRasterPush "osm_raster" {
        sphere_count: u32,
        /// Footprints above this many texels go to band jobs.
        big_area: u32,
        job_capacity: u32,
        /// Optical depth of one sphere, fixed point 2^16.
        tau_fixed: u32,
        slices: u32,
        /// Light depth (relative to the light's centre plane) of slice 0's start.
        z_min: f32,
        /// Slices per world unit.
        inv_dz: f32,
        pad: u32,
    }

    /// `osm_prefix` (glsl/osm_prefix.comp).
    PrefixPush "osm_prefix" {
        /// N * N.
        texels: u32,
        slices: u32,
        /// 2^-16: fixed point -> optical depth.
        inv_scale: f32,
    }

    /// `issm_resolve` (glsl/issm_resolve.comp).
    ResolvePush "issm_resolve" {
        texels: u32,
    }
}

gpu_spec! {
    /// The switches compiled into a `shade` pipeline (glsl/shade.comp).
    ShadeSpec "shade" {
        /// ISSM soft shadows.
        soft: bool = SOFT,
        /// SSDO ran: read (and upsample) its result.
        ao: bool = AO,
        /// Write BGRA (swapchains that want it).
        swap_rb: bool = SWAP_RB,
        /// A light-space technique's lookup (not none, not the screen march).
        use_shadow: bool = USE_SHADOW,
        /// Write the shadow and ao AOVs (read_shadow, read_ambient, --aov
        /// shadow|ao): 4 B/px less traffic and memory without.
        aovs: bool = AOVS,
        /// ISSM t <= 1: only the dense 3x3 core is read (lookup_issm.glsl).
        core_only: bool = ISSM_CORE_ONLY,
        /// --outline: silhouette lines.
        outline: bool = OUTLINE,
        /// RGBA16 colour (--png-depth 16): two words per pixel, R|G<<16, B|A<<16.
        wide: bool = WIDE,
        /// The SSDO result is per 2x2 block (spheres large on screen): upsample it.
        ao_half: bool = AO_HALF,
        /// The SSDO result is per sphere (spheres a few pixels wide): weight its
        /// directions by the pixel's normal (ssdo_common.glsl sphere_ao_at).
        ao_sphere: bool = AO_SPHERE,
        /// Depth cue (--fog): a constant, because lavapipe runs the straight-line
        /// code of an if no lane takes (the fog's background and pows every pixel).
        fog: bool = FOG,
        /// Perspective camera (surface.glsl, shared.glsl's view functions).
        perspective: bool = PERSP,
        /// ISSM t = 0: the 2x2 texels around P (lookup_issm.glsl).
        quad: bool = ISSM_QUAD,
        /// See-through spheres: composite the pixel's fragment list over it.
        see_through: bool = SEE_THROUGH,
    }

    /// The switches of an `ssdo_prep` pipeline (glsl/ssdo_prep.comp).
    PrepSpec "ssdo_prep" {
        /// ISSM soft shadows.
        soft: bool = SOFT,
        /// ISSM: only the dense 3x3 core is read (lookup_issm.glsl).
        core_only: bool = ISSM_CORE_ONLY,
        /// Per-sphere SSDO (ssdo_sphere.comp): mark every sphere seen in the block.
        mark: bool = MARK,
        /// Perspective camera (surface.glsl, shared.glsl's view functions).
        perspective: bool = PERSP,
        /// ISSM t = 0: the 2x2 texels around P (lookup_issm.glsl).
        quad: bool = ISSM_QUAD,
    }

    /// The switches of a per-pixel or per-block `ssdo` pipeline (glsl/ssdo.comp).
    SsdoSpec "ssdo" {
        /// Semantic region test (else plain SSDO).
        semantic: bool = SEMANTIC,
        /// Directions per receiver.
        dirs: u32 = DIRS,
        /// Far-search steps per direction.
        steps: u32 = STEPS,
        /// Perspective camera: the taps work in world space. Orthographic:
        /// in view space, where a tap's projection and the occluder's
        /// position are two multiply-adds each instead of dot products and
        /// divides.
        perspective: bool = PERSP,
        /// Half resolution: one receiver per 2x2 block (spheres large on
        /// screen, where the AO is smooth over a block); else one per pixel.
        half: bool = HALF,
    }

    /// The switches of a per-sphere `ssdo` pipeline (glsl/ssdo_sphere.comp).
    SphereSpec "ssdo_sphere" {
        /// Semantic region test (else plain SSDO).
        semantic: bool = SEMANTIC,
        /// Taps per azimuth line.
        steps: u32 = STEPS,
        /// Perspective camera.
        perspective: bool = PERSP,
    }

    /// The switches of a blur pipeline (glsl/blur.comp).
    BlurSpec "blur" {
        /// 0 horizontal, 1 vertical.
        vertical: u32 = AXIS,
        /// Semantic region test (else plain SSDO).
        semantic: bool = SEMANTIC,
        /// Taps on each side, in pixels or (HALF) blocks: a constant so the
        /// loop unrolls and its spatial weights fold (lavapipe runs a loop to
        /// its slowest lane).
        radius: i32 = RADIUS,
        /// Per 2x2 block (else per pixel).
        half: bool = HALF,
    }
}

# SPDX-License-Identifier: GPL-2.0-or-later
"""Artist preview of a Crisp filter in the 3D viewport (issue 7).

When on, a POST_PIXEL draw handler renders the view into an offscreen buffer each redraw
(GPUOffScreen.draw_view3d, colour-managed: what the viewport shows), decodes it to linear with the sRGB
curve, runs the chosen filter's GLSL twin (gpu_filters.py), and draws the result sRGB-encoded over the
region. For taa the projection is jittered each redraw as the renders are (render.jitter_offset: the
panel's Jitter distribution over EEVEE's filter size), the history is kept between redraws and reset when
the view matrix, projection, size, method, jitter or the filter's settings (scene.crisp) change; while the history holds fewer than ACCUMULATE_FRAMES frames the preview
asks for another redraw. Settings the library rejects (native.check_params: an even REPAIR patchSize,
feedbackMin > feedbackMax) are not run: the view is left unfiltered and the panel shows the library's
message until they are valid again.
Motion vectors and depth are not available to an add-on in the viewport (BLENDER.md), so taa runs its
static path: moving the view, editing the scene or changing frame restarts the accumulation.

When off, no handler is installed (the viewport does not pay anything). Where the gpu module is not
available (background mode) switching it on switches it back off with a message.

Measured on Blender 3.4.1 (llvmpipe) by tests/blender_gui/test_viewport_preview.py:
* Creating framebuffers and draw_view3d inside the handler leave another framebuffer bound than the
  region's: drawing the result there showed nothing (the "black preview"). See _draw_preview.
* The framebuffer a POST_PIXEL handler draws into is the view's overlay buffer, merged over the shaded
  view in "display linear" space (display value ^ 2.2), so the result is written opaque in that space
  (gpu_filters DISPLAY_PASS). The offscreen image is the composited, colour-managed view (display values,
  decoded by the sRGB curve before filtering) with the 3D overlays (grid, outlines), which are filtered
  with the scene.
* draw_view3d draws as an image render, anti-aliased by the scene's settings (ONE_SAMPLE): those are set
  to one sample while the preview is on, so its input is the aliased view (equal to it within 3/255).
* Everything the region draws before POST_PIXEL (the view name text, the navigation gizmo) is covered
  while the preview is on, and so is the camera view's passepartout (draw_view3d does not draw it).

Differences from the filters on final renders: the input is the colour-managed viewport image decoded
by the sRGB curve (equal to linear light with the Standard view transform; with Filmic it is Filmic's
output).
"""

import functools

import bpy
from mathutils import Matrix

METHODS = (("fxaa", "FXAA", "FXAA 3.11 quality (spatial)"),
           ("repair", "REPAIR", "REPAIR rotated spatial filtering (spatial)"),
           ("taa", "TAA", "Temporal AA baseline, jittered projection, static accumulation"))
ACCUMULATE_FRAMES = 16  # taa: redraws requested after the view stops changing (Halton period of the library)


# draw_view3d draws as an image render: workbench anti-aliases it by scene.display.viewport_aa (FXAA by
# default: measured, 54% of the edge pixels of the still_life view changed) and EEVEE renders all its
# viewport samples in one call. The preview must filter the 1-sample view, so these are set while it is
# on and restored when it goes off (and around a save: the file keeps the user's values).
ONE_SAMPLE = (("display", "viewport_aa", "OFF"), ("eevee", "taa_samples", 1))
# On the scene while ONE_SAMPLE is forced: {"group.name": the user's value}. Part of the scene, so each
# undo step says whether it was taken with the forced values and which values they replaced (_after_undo).
# Not in saved files (_before_save removes it); "_": not shown among the scene's custom properties.
FORCED_KEY = "_crisp_preview_forced"


class _State:
    handle = None        # the draw handler, or None when the preview is off
    filters = {}         # (region, method) -> gpu_filters.GpuFilter: each 3D view keeps its own history
    offscreen = None
    offscreen_size = None
    decoded = None       # gpu_filters.Target: the linear input
    stack_guard = None   # a 4x4 offscreen bound around the work to restore the region's framebuffer
    saved_settings = {}  # scene name -> [(group, name, value before)] of ONE_SAMPLE: the scenes forced
    forced_while_saving = None  # saved_settings put back for a save, forced again after it
    pending_off = None   # the timer that switches the preview off after a failed draw, until it runs
    views = {}           # region -> (view key, taa's index into the Halton sequence); {}: every view restarts
    last_region = None   # the region drawn last (accumulated_frames)
    rejected = None      # the library's message when it rejects the scene's settings (not filtered), else None
    drawing = False      # re-entrancy guard (draw_view3d inside a draw handler)
    last_ms = 0.0

MAX_VIEWS = 8  # regions with a filter of their own; more (views closed and opened) start the set afresh


def gpu_unavailable_reason():
    """None when the gpu module can be used here, else why not."""
    if bpy.app.background:
        return "the GPU module is not available in background mode (run Blender with a window)"
    try:
        import gpu  # noqa: F401
        import gpu.shader  # noqa: F401
    except Exception as e:  # pragma: no cover - depends on the build
        return "the GPU module is not available: %s" % e
    return None


@functools.lru_cache(maxsize=8)
def _jitter_reach(distribution, filter_size):
    """The largest |offset| of the preview's jitter period (render.jitter_offset), in pixels."""
    from . import render
    return max(max(abs(v) for v in render.jitter_offset(k, distribution, filter_size, period=ACCUMULATE_FRAMES)[:2])
               for k in range(ACCUMULATE_FRAMES))


def jittered_projection(projection, sx, sy, width, height):
    """projection whose pixel centres sample the view at (+sx, +sy) pixels (x right, y up): the image is
    moved by (-sx, -sy) pixels, a translation of -2 sx / width in NDC after the perspective divide, i.e.
    T @ P (works for perspective and orthographic views)."""
    return Matrix.Translation((-2.0 * sx / width, -2.0 * sy / height, 0.0)) @ projection


def _settings(context):
    return context.window_manager.crisp_viewport


def _filter_params(context, method):
    """The scene's parameters for `method` (scene.crisp, built from the library's table) that the GPU
    version has, as the renders send them (properties.param_value: a saved choice the library no longer
    offers by its name, so the panel's refusal names it), and taa's filterSize from the scene's Film >
    Filter Size; defaults when the add-on's settings are unavailable."""
    from . import gpu_filters
    out = {}
    try:
        from . import properties
        group = properties.param_group(context.scene.crisp, method)
    except Exception:
        group = None
    if group is not None:
        for name in gpu_filters.DEFAULTS[method]:
            if hasattr(group, name):
                out[name] = properties.param_value(group, method, name)
    if "filterSize" in gpu_filters.DEFAULTS[method]:  # as the renders are filtered (pipeline.with_scene_filter_size)
        from . import pipeline
        out["filterSize"] = max(float(context.scene.render.filter_size), pipeline.MIN_FILTER_SIZE)
    return out


def _tag_redraw():
    wm = bpy.context.window_manager
    for window in wm.windows:
        for area in window.screen.areas:
            if area.type == "VIEW_3D":
                area.tag_redraw()
    return None


def _draw():
    if _State.drawing:
        return
    _State.drawing = True
    try:
        _draw_preview(bpy.context)
    except Exception as e:
        message = "Crisp preview off: %s" % e
        print(message)
        if _State.pending_off is None:  # one switch-off: each view's failed draw must not queue another
            _State.pending_off = lambda: _switch_off(message)
            bpy.app.timers.register(_State.pending_off, first_interval=0.0)
    finally:
        _State.drawing = False


def _draw_preview(context):
    import time

    import gpu

    from . import gpu_filters

    t0 = time.perf_counter()
    region, space, rv3d = context.region, context.space_data, context.region_data
    if region is None or rv3d is None or space is None or space.type != "VIEW_3D":
        return
    width, height = region.width, region.height
    if width < 4 or height < 4:
        return
    if _follow_windows(context):
        return  # as Blender drew it: the forced settings reach the scene's evaluated copy after this draw
    # The result must be drawn into the framebuffer bound when the handler starts (the region's). Creating
    # framebuffers and draw_view3d bind others and do not restore it (Blender 3.4): drawing after them
    # went elsewhere, the "black preview". Binding a small offscreen pushes the region's framebuffer on
    # the GPU framebuffer stack; leaving the `with` pops and binds it again.
    blend = gpu.state.blend_get()
    with _State.stack_guard.bind():
        out, filt, method = _filter_view(context, region, space, rv3d, width, height)
    if out is None:  # settings the library rejects: the view stays as Blender drew it
        return
    gpu.state.blend_set("NONE")
    gpu.state.depth_test_set("NONE")
    gpu_filters.draw_display(out, width, height)
    gpu.state.blend_set(blend)
    if method == "taa" and filt.frames < ACCUMULATE_FRAMES and not bpy.app.timers.is_registered(_tag_redraw):
        bpy.app.timers.register(_tag_redraw, first_interval=0.0)
    _State.last_ms = 1000.0 * (time.perf_counter() - t0)


def _filter_view(context, region, space, rv3d, width, height):
    """Renders the view (jittered for taa) into the offscreen buffer and filters it; returns (output
    texture, filter, method), the texture None when the library rejects the scene's settings."""
    import gpu

    from . import gpu_filters, render

    method = _settings(context).method
    # Each 3D view (region) has its own filter and history: views of a split layout draw in turn, and
    # one shared history would restart at every draw.
    region_key = region.as_pointer()
    filt = _State.filters.get((region_key, method))
    if filt is None:
        if len(_State.filters) >= MAX_VIEWS:
            _State.filters, _State.views = {}, {}
        # The offscreen's row 0 is the bottom of the view (common.glsl "Row order").
        filt = _State.filters[(region_key, method)] = gpu_filters.GpuFilter(method, rows_up=True)
    _State.last_region = region_key
    params = _filter_params(context, method)
    rejected = None
    try:
        filt.set_params(params)
    except gpu_filters.GpuParamsError as e:
        rejected = str(e)
        if "'filterSize'" in rejected:  # not a Crisp setting: the scene's (_filter_params)
            rejected = "the scene's Film > Filter Size (%g px): %s" % (context.scene.render.filter_size, rejected)
    if rejected is None:
        view = rv3d.view_matrix.copy()
        projection = rv3d.window_matrix.copy()
        # The renders' jitter (render.render_frames: the panel's Jitter over EEVEE's filter size, which
        # uniform jitter ignores), so the preview settles on the same pixel filter as the filtered renders.
        scene = context.scene
        distribution = scene.crisp.jitter_distribution
        filter_size = scene.render.filter_size if distribution == "blackman-harris" else None
        # Settings edits (scene.crisp) fire no depsgraph update (_on_scene_change): they are part of the key.
        key = (tuple(tuple(r) for r in view), tuple(tuple(r) for r in projection), width, height, method,
               tuple(sorted(params.items())), distribution, filter_size)
        seen, frame = _State.views.get(region_key, (None, 0))
        if key != seen:
            frame = 0
            filt.reset()
        _State.views[region_key] = (key, frame + 1)
        if method == "taa":
            # The widest offset of the period first, so a filter size whose jitter leaves taa's range is
            # said once, not on some redraws of the period.
            reach = _jitter_reach(distribution, filter_size or 0.0)
            why = gpu_filters.library_check(method, dict(filt.params, jitterX=reach, jitterY=reach))
            if why is not None:
                rejected = "the Jitter at the scene's filter size (%g px) reaches %.2f px: %s" % (
                    filter_size, reach, why)
            else:
                sx, sy, _ = render.jitter_offset(frame, distribution, filter_size or 0.0, period=ACCUMULATE_FRAMES)
                # taa's jitterY is along the texture's rows (common.glsl "Row order"); offscreen row 0 is
                # the bottom, so it is y up, like sy.
                filt.set_params({"jitterX": sx, "jitterY": sy})
                projection = jittered_projection(projection, sx, sy, width, height)
    if rejected != _State.rejected:
        _State.rejected = rejected
        if not bpy.app.timers.is_registered(_tag_redraw):  # the panel shows it
            bpy.app.timers.register(_tag_redraw, first_interval=0.0)
    if rejected is not None:
        return None, filt, method

    if _State.offscreen_size != (width, height):
        if _State.offscreen is not None:
            _State.offscreen.free()
        _State.offscreen = gpu.types.GPUOffScreen(width, height, format="RGBA32F")
        _State.decoded = gpu_filters.Target(width, height)
        _State.offscreen_size = (width, height)
    _State.offscreen.draw_view3d(context.scene, context.view_layer, space, region, view, projection,
                                 do_color_management=True)
    gpu_filters.run_pass("decode", _State.decoded, {"colorImage": _State.offscreen.texture_color})
    return filt.run(_State.decoded.texture, width, height), filt, method


def _on_scene_change(*_args):
    """An edit, a selection or a frame change: taa's history no longer matches the scene (there are no
    motion vectors to reproject it), so it restarts."""
    if not _State.drawing:
        _State.views = {}


_SCENE_HANDLERS = (bpy.app.handlers.depsgraph_update_post, bpy.app.handlers.frame_change_post)


def _apply_one_sample(scene):
    """Sets ONE_SAMPLE on scene; returns [(group, name, value before)] of those it changed."""
    changed = []
    for group, name, value in ONE_SAMPLE:
        owner = getattr(scene, group)
        if getattr(owner, name) != value:
            changed.append((group, name, getattr(owner, name)))
            setattr(owner, name, value)
    return changed


def _force_one_sample(scene):
    saved = _apply_one_sample(scene)
    _State.saved_settings[scene.name] = saved
    _mark_forced(scene, saved)


def _follow_windows(context):
    """The preview forces the scenes that windows show: the one drawn now, if a window switched to it
    (True: this draw still has its old settings, the next has the forced ones), and the user's values go
    back to a forced scene no window shows any more."""
    shown = {w.scene.name for w in context.window_manager.windows}
    for name in [n for n in _State.saved_settings if n not in shown and n != context.scene.name]:
        _restore_settings(name)
    if context.scene.name in _State.saved_settings:
        return False
    _force_one_sample(context.scene)
    _State.views = {}
    if not bpy.app.timers.is_registered(_tag_redraw):
        bpy.app.timers.register(_tag_redraw, first_interval=0.0)
    return True


def _mark_forced(scene, saved):
    scene[FORCED_KEY] = {"%s.%s" % (group, name): value for group, name, value in saved}


def _put_back(scene, saved):
    """The user's values `saved` ([(group, name, value)]) where scene still has the forced ones."""
    forced = {(group, name): value for group, name, value in ONE_SAMPLE}
    for group, name, value in saved:
        if getattr(getattr(scene, group), name) == forced[(group, name)]:
            setattr(getattr(scene, group), name, value)
    if FORCED_KEY in scene:
        del scene[FORCED_KEY]


def _restore_settings(only=None):
    """The user's values back in every forced scene, or in the one named `only`."""
    for scene_name in [only] if only is not None else list(_State.saved_settings):
        saved = _State.saved_settings.pop(scene_name)
        scene = bpy.data.scenes.get(scene_name)
        if scene is not None:
            for group, name, value in saved:
                setattr(getattr(scene, group), name, value)
            if FORCED_KEY in scene:
                del scene[FORCED_KEY]


def _install():
    if _State.handle is None:
        _force_one_sample(bpy.context.scene)
        import gpu
        _State.stack_guard = gpu.types.GPUOffScreen(4, 4)  # see _draw_preview
        _State.handle = bpy.types.SpaceView3D.draw_handler_add(_draw, (), "WINDOW", "POST_PIXEL")
        for handlers in _SCENE_HANDLERS:
            handlers.append(_on_scene_change)
        _State.views = {}
    _tag_redraw()


def _remove():
    if _State.handle is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_State.handle, "WINDOW")
        _State.handle = None
        for handlers in _SCENE_HANDLERS:
            if _on_scene_change in handlers:
                handlers.remove(_on_scene_change)
        _restore_settings()
    _State.filters = {}
    for offscreen in (_State.offscreen, _State.stack_guard):
        if offscreen is not None:
            offscreen.free()
    _State.offscreen = _State.offscreen_size = _State.decoded = _State.stack_guard = None
    _State.views, _State.last_region, _State.rejected = {}, None, None
    try:
        _tag_redraw()
    except Exception:
        pass


def _switch_off(message):
    _State.pending_off = None
    wm = bpy.context.window_manager
    s = wm.crisp_viewport
    s.status = message
    if s.enabled:
        s.enabled = False  # update callback removes the handler
    else:
        _remove()
    return None


def _on_enabled(self, context):
    if self.enabled:
        why = gpu_unavailable_reason()
        if why is not None:
            self.status = "Crisp preview off: " + why
            print(self.status)
            self.enabled = False
            return
        self.status = ""
        _install()
    else:
        _remove()


def _on_method(self, context):
    _State.views = {}
    if self.enabled:
        _tag_redraw()


def is_active():
    return _State.handle is not None


def last_draw_ms():
    """CPU time of the last preview redraw (the GPU may still be working when it ends)."""
    return _State.last_ms


def rejected_settings():
    """The library's message when it rejects the scene's settings for the preview's method (the view is
    then not filtered), else None."""
    return _State.rejected if _State.handle is not None else None


def accumulated_frames():
    """taa: redraws accumulated in the history of the view drawn last since its reset (0 for the spatial
    methods)."""
    filt = _State.filters.get((_State.last_region, "taa"))
    return filt.frames if filt is not None and _State.handle is not None else 0


class CrispViewportSettings(bpy.types.PropertyGroup):
    enabled: bpy.props.BoolProperty(
        name="Crisp Preview", default=False, update=_on_enabled,
        description="Filter the 3D viewport with the chosen Crisp method (GPU version of the library's filter)")
    method: bpy.props.EnumProperty(name="Method", items=METHODS, default="fxaa", update=_on_method,
                                   description="Filter used by the viewport preview")
    status: bpy.props.StringProperty(name="Status", default="")


class CRISP_PT_viewport(bpy.types.Panel):
    bl_label = "Crisp Preview"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Crisp"

    def draw(self, context):
        s = _settings(context)
        layout = self.layout
        layout.prop(s, "enabled")
        layout.prop(s, "method")
        if s.status:
            row = layout.row()
            row.alert = True
            row.label(text=s.status, icon="ERROR")
        elif rejected_settings():
            row = layout.row()
            row.alert = True
            row.label(text="Not filtered: " + rejected_settings(), icon="ERROR")
        elif is_active():
            layout.label(text="%.1f ms per redraw" % _State.last_ms)
        if _State.saved_settings.get(context.scene.name):
            layout.label(text="While on: " + ", ".join("%s.%s = %r" % (g, n, v) for g, n, v in ONE_SAMPLE),
                         icon="INFO")


def _header_toggle(self, context):
    s = _settings(context)
    self.layout.prop(s, "enabled", text="", icon="ANTIALIASED")


@bpy.app.handlers.persistent
def _before_file_load(*_args):
    """File > Open (or New, or Revert): the preview ends with the file it filters, its settings put back
    in that file's scene (not in a same-named scene of the next file), its handlers gone; the next
    file starts with the toggle off (also with Load UI off, which keeps this window manager)."""
    _remove()
    s = getattr(bpy.context.window_manager, "crisp_viewport", None)
    if s is not None and s.enabled:
        s.enabled = False  # its update callback finds nothing left to remove


@bpy.app.handlers.persistent
def _before_save(*_args):
    """The file is saved with the user's sample settings, not the one sample forced while the preview is on."""
    if _State.saved_settings:
        _State.forced_while_saving = list(_State.saved_settings)
        _restore_settings()


@bpy.app.handlers.persistent
def _after_save(*_args):
    names, _State.forced_while_saving = _State.forced_while_saving, None
    if names is not None and is_active():
        for scene in filter(None, map(bpy.data.scenes.get, names)):
            _force_one_sample(scene)


@bpy.app.handlers.persistent
def _after_undo(*_args):
    """Undo and redo bring the scene back as it was at that step, with the sample settings it had then:
    forced ones (and FORCED_KEY) from a step taken while the preview was on, the user's from one taken
    before. While the preview is on, its scenes are forced again; every other scene that comes back forced
    (the preview off since, or on in another scene) gets the user's values that step recorded. A step
    taken after the preview went off keeps its values, even one sample chosen by the user."""
    active = _State.saved_settings if is_active() else {}
    for scene in bpy.data.scenes:
        if scene.name in active:
            _apply_one_sample(scene)  # forced again; the user's values stay those saved when it was forced
            if FORCED_KEY not in scene:
                _mark_forced(scene, active[scene.name])
        elif FORCED_KEY in scene:
            _put_back_recorded(scene)


def _put_back_recorded(scene):
    """The user's values that scene's FORCED_KEY recorded, where it still has the forced ones."""
    recorded = scene[FORCED_KEY].to_dict()
    _put_back(scene, [(g, n, recorded[g + "." + n]) for g, n, _v in ONE_SAMPLE if g + "." + n in recorded])


@bpy.app.handlers.persistent
def _after_file_load(*_args):
    """An auto save and the last session's quit.blend are written without the save handlers, so a scene
    the preview forced comes back forced, with FORCED_KEY; the preview is off after a load (it ends with
    the file it filtered), so the user's values go back."""
    for scene in bpy.data.scenes:
        if FORCED_KEY in scene:
            _put_back_recorded(scene)


_FILE_HANDLERS = ((bpy.app.handlers.load_pre, _before_file_load), (bpy.app.handlers.load_post, _after_file_load),
                  (bpy.app.handlers.save_pre, _before_save),
                  (bpy.app.handlers.save_post, _after_save), (bpy.app.handlers.undo_post, _after_undo),
                  (bpy.app.handlers.redo_post, _after_undo))


def register():
    for handlers, handler in _FILE_HANDLERS:
        handlers.append(handler)
    bpy.utils.register_class(CrispViewportSettings)
    bpy.types.WindowManager.crisp_viewport = bpy.props.PointerProperty(type=CrispViewportSettings)
    bpy.utils.register_class(CRISP_PT_viewport)
    bpy.types.VIEW3D_HT_header.append(_header_toggle)


def unregister():
    _remove()
    # The toggle's value outlives the property (it is kept on the window manager): off, so that the
    # add-on enabled again does not show it on with nothing drawing. A switch-off still queued goes too.
    for wm in bpy.data.window_managers:
        s = getattr(wm, "crisp_viewport", None)
        if s is not None and s.enabled:
            s.enabled = False
    for timer in (_State.pending_off, _tag_redraw):
        if timer is not None and bpy.app.timers.is_registered(timer):
            bpy.app.timers.unregister(timer)
    _State.pending_off = None
    for handlers, handler in _FILE_HANDLERS:
        if handler in handlers:
            handlers.remove(handler)
    bpy.types.VIEW3D_HT_header.remove(_header_toggle)
    bpy.utils.unregister_class(CRISP_PT_viewport)
    del bpy.types.WindowManager.crisp_viewport
    bpy.utils.unregister_class(CrispViewportSettings)

//! The interactive window (winit): orbit/fly camera, debug views and
//! settings on keys, fps and help in the title bar.

use super::camera::{Camera, Mode};
use super::headless::write_png;
use super::live::LiveView;
use super::model::Model;
use super::options::{initial_camera, Options, ToneMap, ViewMode};
use super::renderer::Renderer;
use super::watch::Watch;
use anyhow::{anyhow, Context as _, Result};
use glam::Vec3;
use std::collections::HashSet;
use std::sync::Arc;
use std::time::Instant;
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

/// The keys, as printed by `H` and in docs/preview.md.
pub const HELP: &str = "\
mouse: left drag orbit/look, right or middle drag pan, wheel zoom
Tab: orbit <-> fly camera    W A S D: move (fly), Q/E: down/up, Shift: faster
1 lit  2 lightmap  3 albedo  4 texel checker  5 chart borders  6 patches  7 invalid texels  8 probes  9 distance field
B: bilinear/bicubic lightmap   T: tone map ACES/none   +/-: exposure   0: exposure 0
PageUp/PageDown: move the distance field's slice (Shift: 10 voxels)   G: distance-field shadows on/off
F: reset camera   P: screenshot (preview_<n>.png)   H: help   Esc: quit
--live: Left/Right: the sun's azimuth, Up/Down: its elevation (Shift: faster)";

struct State {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    renderer: Renderer,
    adapter: String,
}

struct App {
    model: Model,
    opts: Options,
    start_camera: Camera,
    state: Option<State>,
    error: Option<anyhow::Error>,
    keys: HashSet<KeyCode>,
    buttons: HashSet<MouseButton>,
    cursor: Option<(f64, f64)>,
    last_frame: Instant,
    fps_since: Instant,
    fps_frames: u32,
    fps: f64,
    frames: u32,
    screenshots: u32,
    /// `--watch`: the bake being followed, and when it was last looked at.
    watch: Option<Watch>,
    watched: Instant,
    /// `--live`: the live bake whose sun the arrow keys turn.
    live: Option<LiveView>,
}

impl App {
    fn init(&mut self, event_loop: &ActiveEventLoop) -> Result<()> {
        let (w, h) = self.opts.size;
        let attrs = Window::default_attributes()
            .with_title("radbake preview")
            .with_inner_size(PhysicalSize::new(w, h));
        let window = Arc::new(
            event_loop
                .create_window(attrs)
                .context("cannot create a window")?,
        );
        let instance = crate::util::adapter::instance(
            wgpu::Backends::all(),
            Some(Box::new(event_loop.owned_display_handle())),
        );
        let surface = instance
            .create_surface(window.clone())
            .context("cannot create a window surface")?;
        let (adapter, device, queue) = crate::util::adapter::device(&instance, Some(&surface))?;
        let size = window.inner_size();
        let mut config = surface
            .get_default_config(&adapter, size.width.max(1), size.height.max(1))
            .ok_or_else(|| anyhow!("the adapter cannot present to this window"))?;
        let caps = surface.get_capabilities(&adapter);
        // Prefer an sRGB surface (its content is sRGB-encoded), drawn through
        // its plain twin: the shader encodes, as three.js's does.
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| f.is_srgb())
            .unwrap_or(config.format);
        config.format = format;
        let view_format = format.remove_srgb_suffix();
        if view_format != format {
            config.view_formats = vec![view_format];
        }
        config.present_mode = if self.opts.frames.is_some() {
            wgpu::PresentMode::AutoNoVsync
        } else {
            wgpu::PresentMode::AutoVsync
        };
        surface.configure(&device, &config);
        let mut renderer = Renderer::new(
            &device,
            &queue,
            view_format,
            &self.model,
            self.start_camera.clone(),
            self.opts.settings,
        );
        renderer.resize(config.width, config.height);
        let adapter = crate::util::adapter::describe(&adapter);
        eprintln!("radbake preview on {adapter}\n{HELP}");
        self.state = Some(State {
            window,
            surface,
            config,
            renderer,
            adapter,
        });
        Ok(())
    }

    fn title(&self) -> String {
        let Some(s) = &self.state else {
            return "radbake preview".into();
        };
        let st = &s.renderer.settings;
        let sun = self.live.as_ref().map_or(String::new(), |l| {
            format!(
                " | sun {:.1}° up, {:.1}° round: {:.1} ms ({} it.)",
                l.elevation, l.azimuth, l.update_ms, l.iterations
            )
        });
        format!(
            "radbake preview — {} | {} | {} | EV {:+.1} | {} | {:.0} fps{sun} | H: help",
            st.view.name(),
            if st.bicubic { "bicubic" } else { "bilinear" },
            match st.tone_map {
                ToneMap::Aces => "ACES",
                ToneMap::None => "no tone map",
            },
            st.exposure_ev,
            match s.renderer.camera.mode {
                Mode::Orbit => "orbit",
                Mode::Fly => "fly",
            },
            self.fps
        )
    }

    /// `--live`: turns the sun while an arrow key is held, and re-solves.
    fn turn_sun(&mut self, dt: f32) -> Result<()> {
        let (Some(live), Some(s)) = (&mut self.live, &mut self.state) else {
            return Ok(());
        };
        let held = |k| self.keys.contains(&k) as i32 as f32;
        let fast =
            self.keys.contains(&KeyCode::ShiftLeft) || self.keys.contains(&KeyCode::ShiftRight);
        let rate = if fast { 60.0 } else { 15.0 } * dt;
        let (de, da) = (
            held(KeyCode::ArrowUp) - held(KeyCode::ArrowDown),
            held(KeyCode::ArrowRight) - held(KeyCode::ArrowLeft),
        );
        if de == 0.0 && da == 0.0 {
            return Ok(());
        }
        live.turn(de * rate, da * rate);
        live.update(&mut self.model, &mut s.renderer)
    }

    fn key(&mut self, code: KeyCode, event_loop: &ActiveEventLoop) -> Result<()> {
        let start = self.start_camera.clone();
        let Some(s) = &mut self.state else {
            return Ok(());
        };
        let r = &mut s.renderer;
        match code {
            KeyCode::Escape => event_loop.exit(),
            KeyCode::Tab => {
                r.camera.mode = match r.camera.mode {
                    Mode::Orbit => Mode::Fly,
                    Mode::Fly => Mode::Orbit,
                }
            }
            KeyCode::Digit1
            | KeyCode::Digit2
            | KeyCode::Digit3
            | KeyCode::Digit4
            | KeyCode::Digit5
            | KeyCode::Digit6
            | KeyCode::Digit7
            | KeyCode::Digit8
            | KeyCode::Digit9 => {
                let i = [
                    KeyCode::Digit1,
                    KeyCode::Digit2,
                    KeyCode::Digit3,
                    KeyCode::Digit4,
                    KeyCode::Digit5,
                    KeyCode::Digit6,
                    KeyCode::Digit7,
                    KeyCode::Digit8,
                    KeyCode::Digit9,
                ]
                .iter()
                .position(|&k| k == code)
                .unwrap_or(0);
                r.settings.view = ViewMode::ALL[i];
            }
            KeyCode::PageUp | KeyCode::PageDown => {
                let shift = self.keys.contains(&KeyCode::ShiftLeft)
                    || self.keys.contains(&KeyCode::ShiftRight);
                let sign = if code == KeyCode::PageUp { 1.0 } else { -1.0 };
                r.move_slice(sign * if shift { 10.0 } else { 1.0 });
            }
            KeyCode::KeyG => r.settings.sdf_shadows = !r.settings.sdf_shadows,
            KeyCode::KeyB => r.settings.bicubic = !r.settings.bicubic,
            KeyCode::KeyT => {
                r.settings.tone_map = match r.settings.tone_map {
                    ToneMap::Aces => ToneMap::None,
                    ToneMap::None => ToneMap::Aces,
                }
            }
            KeyCode::Equal | KeyCode::NumpadAdd => r.settings.exposure_ev += 0.5,
            KeyCode::Minus | KeyCode::NumpadSubtract => r.settings.exposure_ev -= 0.5,
            KeyCode::Digit0 => r.settings.exposure_ev = 0.0,
            KeyCode::KeyF => r.camera = start,
            KeyCode::KeyH => eprintln!("{HELP}"),
            KeyCode::KeyP => {
                let path = std::path::PathBuf::from(format!("preview_{}.png", self.screenshots));
                self.screenshots += 1;
                let (w, h) = r.size();
                let rgba = r.render_to_image()?;
                write_png(&path, w, h, &rgba)?;
                eprintln!("wrote {}", path.display());
            }
            _ => {}
        }
        Ok(())
    }

    /// `--watch`: every 250 ms, reload the model if the bake wrote a newer
    /// file, keeping the camera, the settings and the distance field. A
    /// file that cannot be read keeps the picture as it is, with a warning.
    fn follow(&mut self) {
        if self.watched.elapsed().as_millis() < 250 {
            return;
        }
        self.watched = Instant::now();
        let (Some(w), Some(s)) = (&mut self.watch, &mut self.state) else {
            return;
        };
        let Some(path) = w.changed() else {
            return;
        };
        let mut model = match Model::load_weighted(&path, &self.opts.layers) {
            Ok(m) => m,
            Err(e) => {
                eprintln!("warning: --watch: {}: {e:#}", path.display());
                return;
            }
        };
        if model.field.is_none() {
            model.field = self.model.field.take();
        }
        let r = &s.renderer;
        let (device, queue) = (r.device().clone(), r.queue().clone());
        let mut renderer = Renderer::new(
            &device,
            &queue,
            r.format(),
            &model,
            r.camera.clone(),
            r.settings,
        );
        renderer.resize(s.config.width, s.config.height);
        s.renderer = renderer;
        self.model = model;
        eprintln!("reloaded {}", path.display());
    }

    fn frame(&mut self, event_loop: &ActiveEventLoop) -> Result<()> {
        self.follow();
        let now = Instant::now();
        let dt = (now - self.last_frame).as_secs_f32().min(0.1);
        self.last_frame = now;
        self.turn_sun(dt)?;
        let Some(s) = &mut self.state else {
            return Ok(());
        };
        // Fly movement from held keys.
        let held = |k| self.keys.contains(&k) as i32 as f32;
        let dir = Vec3::new(
            held(KeyCode::KeyD) - held(KeyCode::KeyA),
            held(KeyCode::KeyE) - held(KeyCode::KeyQ),
            held(KeyCode::KeyW) - held(KeyCode::KeyS),
        );
        if dir != Vec3::ZERO {
            let fast =
                self.keys.contains(&KeyCode::ShiftLeft) || self.keys.contains(&KeyCode::ShiftRight);
            s.renderer.camera.fly(dir, dt, fast);
        }
        let frame = match s.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t)
            | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => {
                return Ok(())
            }
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                let device = s.renderer.device().clone();
                s.surface.configure(&device, &s.config);
                return Ok(());
            }
            wgpu::CurrentSurfaceTexture::Validation => {
                return Err(anyhow!(
                    "the surface texture could not be acquired (validation error)"
                ))
            }
        };
        let view = frame.texture.create_view(&wgpu::TextureViewDescriptor {
            format: Some(s.renderer.format()),
            ..Default::default()
        });
        s.renderer.render(&view);
        s.window.pre_present_notify();
        s.renderer.queue().present(frame);
        self.frames += 1;
        self.fps_frames += 1;
        let since = self.fps_since.elapsed().as_secs_f64();
        if since >= 0.5 {
            self.fps = self.fps_frames as f64 / since;
            self.fps_frames = 0;
            self.fps_since = Instant::now();
            let title = self.title();
            if let Some(s) = &self.state {
                s.window.set_title(&title);
            }
        }
        if let Some(n) = self.opts.frames {
            if self.frames >= n {
                if let (Some(path), Some(s)) = (&self.opts.screenshot, &mut self.state) {
                    let (w, h) = s.renderer.size();
                    let rgba = s.renderer.render_to_image()?;
                    write_png(path, w, h, &rgba)?;
                    eprintln!(
                        "{} frames in the window on {} ({:.1} fps); wrote {}",
                        self.frames,
                        s.adapter,
                        self.fps,
                        path.display()
                    );
                }
                event_loop.exit();
            }
        }
        Ok(())
    }

    fn fail(&mut self, event_loop: &ActiveEventLoop, e: anyhow::Error) {
        self.error.get_or_insert(e);
        event_loop.exit();
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.state.is_none() {
            if let Err(e) = self.init(event_loop) {
                self.fail(event_loop, e);
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let result = match event {
            WindowEvent::CloseRequested => {
                event_loop.exit();
                Ok(())
            }
            WindowEvent::Resized(size) => {
                if let Some(s) = &mut self.state {
                    if size.width > 0 && size.height > 0 {
                        s.config.width = size.width;
                        s.config.height = size.height;
                        let device = s.renderer.device().clone();
                        s.surface.configure(&device, &s.config);
                        s.renderer.resize(size.width, size.height);
                    }
                }
                Ok(())
            }
            WindowEvent::KeyboardInput { event, .. } => {
                let PhysicalKey::Code(code) = event.physical_key else {
                    return;
                };
                match event.state {
                    ElementState::Pressed => {
                        self.keys.insert(code);
                        if event.repeat {
                            Ok(())
                        } else {
                            self.key(code, event_loop)
                        }
                    }
                    ElementState::Released => {
                        self.keys.remove(&code);
                        Ok(())
                    }
                }
            }
            WindowEvent::MouseInput { state, button, .. } => {
                match state {
                    ElementState::Pressed => self.buttons.insert(button),
                    ElementState::Released => self.buttons.remove(&button),
                };
                Ok(())
            }
            WindowEvent::CursorMoved { position, .. } => {
                let (x, y) = (position.x, position.y);
                if let (Some((px, py)), Some(s)) = (self.cursor, &mut self.state) {
                    let (dx, dy) = ((x - px) as f32, (y - py) as f32);
                    let cam = &mut s.renderer.camera;
                    if self.buttons.contains(&MouseButton::Left) {
                        cam.rotate(dx, dy);
                    } else if self.buttons.contains(&MouseButton::Right)
                        || self.buttons.contains(&MouseButton::Middle)
                    {
                        cam.pan(dx, dy, s.config.height as f32);
                    }
                }
                self.cursor = Some((x, y));
                Ok(())
            }
            WindowEvent::MouseWheel { delta, .. } => {
                let steps = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                if let Some(s) = &mut self.state {
                    s.renderer.camera.zoom(steps);
                }
                Ok(())
            }
            WindowEvent::RedrawRequested => self.frame(event_loop),
            _ => Ok(()),
        };
        if let Err(e) = result {
            self.fail(event_loop, e);
        }
    }

    fn about_to_wait(&mut self, _event_loop: &ActiveEventLoop) {
        if let Some(s) = &self.state {
            s.window.request_redraw();
        }
    }
}

/// Opens the window and runs until it is closed (or `opts.frames` are drawn).
pub fn run(model: Model, opts: &Options, watch: Option<Watch>) -> Result<()> {
    let start_camera = initial_camera(&model, &opts.viewpoint)?;
    let live = if opts.live {
        Some(LiveView::open(
            &opts.scene,
            &opts.layers,
            opts.sun.as_ref(),
        )?)
    } else {
        None
    };
    let event_loop = EventLoop::new().map_err(|e| {
        anyhow!("cannot open a window ({e}); is there a display (DISPLAY/WAYLAND_DISPLAY)? Use --headless to render offscreen")
    })?;
    let mut app = App {
        model,
        opts: opts.clone(),
        start_camera,
        state: None,
        error: None,
        keys: HashSet::new(),
        buttons: HashSet::new(),
        cursor: None,
        last_frame: Instant::now(),
        fps_since: Instant::now(),
        fps_frames: 0,
        fps: 0.0,
        frames: 0,
        screenshots: 0,
        watch,
        watched: Instant::now(),
        live,
    };
    event_loop.run_app(&mut app).context("window event loop")?;
    match app.error {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

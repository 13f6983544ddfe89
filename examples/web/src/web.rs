//! The page's bindings (wasm32): [`WebDemo`] opens the page's WebGPU as WebGPU's core device
//! (no optional feature, default limits) and renders [`Demo`]'s frames into byte arrays the
//! page puts on its canvases (examples/web/demo.mjs).

use std::cell::RefCell;
use std::rc::Rc;

use wasm_bindgen::prelude::*;

use dhoit_runtime::frame::Method;

use crate::{Demo, METHODS, PAGE_METHODS, SCENES};

/// The demo as the page holds it. Calls that render return promises; one call at a time (the
/// page awaits each).
#[wasm_bindgen]
pub struct WebDemo {
    /// The demo, taken out while it renders (so a call meanwhile is refused, not a panic).
    demo: Rc<RefCell<Option<Demo>>>,
    adapter: String,
}

fn js_error(e: impl std::fmt::Display) -> JsValue {
    JsError::new(&e.to_string()).into()
}

fn busy() -> JsValue {
    js_error("the demo is rendering: await render() first")
}

impl WebDemo {
    fn get(&self) -> Result<std::cell::Ref<'_, Demo>, JsValue> {
        std::cell::Ref::filter_map(self.demo.borrow(), Option::as_ref).map_err(|_| busy())
    }

    fn get_mut(&self) -> Result<std::cell::RefMut<'_, Demo>, JsValue> {
        std::cell::RefMut::filter_map(self.demo.borrow_mut(), Option::as_mut).map_err(|_| busy())
    }
}

#[wasm_bindgen]
impl WebDemo {
    /// Opens the page's WebGPU (`navigator.gpu`) and builds dhoit's passes on it: `methods`
    /// (dhoit's names; none: the page's three, [`METHODS`]) rendering `scene` at `width` x
    /// `height` with `budget` (`"25%"`, `"1fpp"`, ...).
    pub async fn start(
        methods: Vec<String>,
        scene: String,
        width: u32,
        height: u32,
        budget: String,
    ) -> Result<WebDemo, JsValue> {
        let methods = match methods.is_empty() {
            true => METHODS.to_vec(),
            false => methods
                .iter()
                .map(|m| m.parse::<Method>())
                .collect::<dhoit_runtime::Result<Vec<_>>>()
                .map_err(js_error)?,
        };
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.backends = wgpu::Backends::BROWSER_WEBGPU;
        let instance = wgpu::Instance::new(desc);
        let adapter = instance
            .request_adapter(&wgpu::RequestAdapterOptions::default())
            .await
            .map_err(|e| js_error(format!("no WebGPU adapter: {e}")))?;
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("dhoit (WebGPU core)"),
                required_features: wgpu::Features::empty(),
                required_limits: wgpu::Limits::default(),
                ..Default::default()
            })
            .await
            .map_err(|e| js_error(format!("opening the WebGPU device: {e}")))?;
        let info = adapter.get_info();
        let adapter = match info.name.is_empty() {
            true => "the page's WebGPU".to_string(),
            false => info.name.clone(),
        };
        let demo = Demo::new(
            device,
            queue,
            &info,
            &methods,
            &scene,
            (width, height),
            &budget,
        )
        .await
        .map_err(js_error)?;
        Ok(WebDemo {
            demo: Rc::new(RefCell::new(Some(demo))),
            adapter,
        })
    }

    /// The camera as 24 f32 bit patterns ([`Demo::camera_bits`]).
    pub fn camera_bits(&self) -> Result<Vec<u32>, JsValue> {
        Ok(self.get()?.camera_bits().to_vec())
    }

    /// Sees the scene through another camera ([`Demo::set_camera_bits`]).
    pub fn set_camera_bits(&self, words: Vec<u32>) -> Result<(), JsValue> {
        self.get_mut()?.set_camera_bits(&words).map_err(js_error)
    }

    /// The scene's vertices as f32 bit patterns ([`Demo::geometry_bits`]).
    pub fn geometry_bits(&self) -> Result<Vec<u32>, JsValue> {
        Ok(self.get()?.geometry_bits())
    }

    /// The scene's vertices replaced ([`Demo::set_geometry_bits`]).
    pub fn set_geometry_bits(&self, words: Vec<u32>) -> Result<(), JsValue> {
        self.get_mut()?.set_geometry_bits(&words).map_err(js_error)
    }

    /// The adapter's name.
    pub fn adapter(&self) -> String {
        self.adapter.clone()
    }

    /// The methods the page shows by default, left to right, as dhoit's command line names
    /// them.
    pub fn methods() -> Vec<String> {
        METHODS.iter().map(|m| m.to_string()).collect()
    }

    /// Every method a page's WebGPU runs ([`PAGE_METHODS`]).
    pub fn page_methods() -> Vec<String> {
        PAGE_METHODS.iter().map(|m| m.to_string()).collect()
    }

    /// The built-in scenes the page offers.
    pub fn scenes() -> Vec<String> {
        SCENES.iter().map(|s| s.to_string()).collect()
    }

    /// DKB's and VKB's budget from the next frame; an error names a budget it cannot take.
    pub fn set_budget(&self, budget: String) -> Result<(), JsValue> {
        self.get_mut()?.set_budget(&budget).map_err(js_error)
    }

    /// The scene shown.
    pub fn scene(&self) -> Result<String, JsValue> {
        Ok(self.get()?.scene().to_string())
    }

    /// Shows another built-in scene.
    pub fn set_scene(&self, scene: String) -> Result<(), JsValue> {
        self.get_mut()?.set_scene(&scene).map_err(js_error)
    }

    /// Every method's frame: a promise of an array of `{method, rgba, linear, bytes, exact,
    /// frames, rmse}`, `rgba` a `Uint8Array` of sRGB RGBA8 (width x height x 4), `linear` a
    /// `Float32Array` of the frame's linear RGB, `rmse` against the A-buffer's frame.
    pub fn render(&self) -> js_sys::Promise {
        let demo = self.demo.clone();
        wasm_bindgen_futures::future_to_promise(async move {
            let mut taken = demo.borrow_mut().take().ok_or_else(busy)?;
            let views = taken.render().await;
            *demo.borrow_mut() = Some(taken);
            let views = views.map_err(js_error)?;
            let reference = views.last().map(|v| v.image.clone());
            let out = js_sys::Array::new();
            for v in &views {
                let o = js_sys::Object::new();
                let set = |k: &str, val: JsValue| js_sys::Reflect::set(&o, &k.into(), &val);
                set("method", v.method.to_string().into())?;
                set("rgba", js_sys::Uint8Array::from(v.rgba.as_slice()).into())?;
                let linear: Vec<f32> = v.image.data.iter().flatten().copied().collect();
                set(
                    "linear",
                    js_sys::Float32Array::from(linear.as_slice()).into(),
                )?;
                set("bytes", (v.bytes as f64).into())?;
                set("exact", v.exact.into())?;
                set("frames", (v.frames as u32).into())?;
                let error = reference.as_ref().map_or(0.0, |r| v.image.mse(r).sqrt());
                set("rmse", error.into())?;
                out.push(&o);
            }
            Ok(out.into())
        })
    }
}

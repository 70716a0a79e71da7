//! The page and three.js, compiled into the binary (see `build.rs`): the studio serves them
//! itself, offline, from any working directory.

/// One embedded file.
pub struct Asset {
    /// URL path.
    pub path: &'static str,
    /// `Content-Type`.
    pub mime: &'static str,
    /// Contents.
    pub body: &'static [u8],
}

macro_rules! web {
    ($file:literal) => {
        include_bytes!(concat!(env!("CARGO_MANIFEST_DIR"), "/web/", $file))
    };
}

const JS: &str = "text/javascript; charset=utf-8";

/// Every file the page loads. three.js's addons import `three` through the page's import map.
pub const ASSETS: &[Asset] = &[
    Asset { path: "/", mime: "text/html; charset=utf-8", body: web!("index.html") },
    Asset { path: "/app.js", mime: JS, body: web!("app.js") },
    Asset { path: "/style.css", mime: "text/css; charset=utf-8", body: web!("style.css") },
    Asset {
        path: "/vendor/three.module.js",
        mime: JS,
        body: web!("node_modules/three/build/three.module.js"),
    },
    Asset { path: "/vendor/three.core.js", mime: JS, body: web!("node_modules/three/build/three.core.js") },
    Asset {
        path: "/vendor/addons/controls/OrbitControls.js",
        mime: JS,
        body: web!("node_modules/three/examples/jsm/controls/OrbitControls.js"),
    },
    Asset {
        path: "/vendor/addons/controls/TransformControls.js",
        mime: JS,
        body: web!("node_modules/three/examples/jsm/controls/TransformControls.js"),
    },
    Asset {
        path: "/vendor/LICENSE-three.txt",
        mime: "text/plain; charset=utf-8",
        body: web!("node_modules/three/LICENSE"),
    },
];

/// The asset at a URL path.
pub fn find(path: &str) -> Option<&'static Asset> {
    let path = if path == "/index.html" { "/" } else { path };
    ASSETS.iter().find(|a| a.path == path)
}

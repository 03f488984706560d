// Renders one glTF with the Khronos glTF Sample Renderer and hands back its linear pixels.
// khronos_render.py serves this page, the renderer's module (with the few changes it lists)
// and the asset's folder, then calls window.renderGltf() over the DevTools protocol.
import { GltfView, GltfState } from "./node_modules/@khronosgroup/gltf-viewer/dist/gltf-viewer.module.js";

// Where the renderer finds mikktspace_bg.wasm (tangents for normal maps without TANGENT).
const LIBS = "node_modules/@khronosgroup/gltf-viewer/dist/libs/";

// The package ships no Draco decoder and these assets use no Draco compression: a stand-in
// that reports an empty decoder, so that the loader does not look for the global one.
const NO_DRACO = (decoderType) => decoderType.onModuleLoaded(null);

// The renderer draws its last pass into the default framebuffer, 8 bits a channel and
// clamped at 1. A float framebuffer of our own stands in for it, so what comes back is the
// shader's value at full precision. 32-bit floats where the context can blend them (alpha
// BLEND needs it), else half floats.
function floatFramebuffer(gl, width, height) {
    if (!gl.getExtension("EXT_color_buffer_float")) {
        throw new Error("no EXT_color_buffer_float: cannot render to a float framebuffer");
    }
    const format = gl.getExtension("EXT_float_blend") ? gl.RGBA32F : gl.RGBA16F;
    const color = gl.createRenderbuffer();
    gl.bindRenderbuffer(gl.RENDERBUFFER, color);
    gl.renderbufferStorage(gl.RENDERBUFFER, format, width, height);
    const depth = gl.createRenderbuffer();
    gl.bindRenderbuffer(gl.RENDERBUFFER, depth);
    gl.renderbufferStorage(gl.RENDERBUFFER, gl.DEPTH_COMPONENT24, width, height);
    const framebuffer = gl.createFramebuffer();
    WebGL2RenderingContext.prototype.bindFramebuffer.call(gl, gl.FRAMEBUFFER, framebuffer);
    gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.RENDERBUFFER, color);
    gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.RENDERBUFFER, depth);
    if (gl.checkFramebufferStatus(gl.FRAMEBUFFER) !== gl.FRAMEBUFFER_COMPLETE) {
        throw new Error("the float framebuffer is incomplete");
    }
    return {framebuffer, format: format === gl.RGBA32F ? "RGBA32F" : "RGBA16F"};
}

// While it is in place, binding the default framebuffer (null) binds `framebuffer`.
function redirectDefaultFramebuffer(gl, framebuffer) {
    const bind = WebGL2RenderingContext.prototype.bindFramebuffer;
    gl.bindFramebuffer = (target, fb) => bind.call(gl, target, fb === null ? framebuffer : fb);
    return () => { delete gl.bindFramebuffer; };
}

// The camera the tracer uses: the first node (in the file's order) that has one.
function firstCameraIndex(gltf) {
    const node = (gltf.nodes || []).find((n) => n.camera !== undefined);
    return node === undefined ? undefined : node.camera;
}

// A camera given by the caller: {eye, target, yfov}.
function useGivenCamera(state, camera) {
    state.cameraIndex = undefined;
    state.userCamera.setVerticalFoV(camera.yfov);
    state.userCamera.lookAt(Float32Array.from(camera.eye), Float32Array.from(camera.target));
}

// One directional light given by the caller ({direction, color, intensity}), used when the
// asset has no lights: the renderer's stand-in key light, its fill light off. Its uniform
// upload takes the direction as a Float32Array only.
function useGivenLight(view, state, light) {
    const renderer = view.renderer;
    state.renderingParameters.useDirectionalLightsWithDisabledIBL = true;
    renderer.lightKey.direction = Float32Array.from(light.direction);
    renderer.lightKey.color = Array.from(light.color || [1, 1, 1]);
    renderer.lightKey.intensity = light.intensity ?? 1;
    renderer.lightFill.intensity = 0;
}

function base64(bytes) {
    let text = "";
    for (let i = 0; i < bytes.length; i += 0x8000) {
        text += String.fromCharCode.apply(null, bytes.subarray(i, i + 0x8000));
    }
    return btoa(text);
}

// options: environment (URL of an .hdr), sheenLut (URL of a PNG), camera, light (both optional).
// Returns {width, height, format, rgba}: rgba is base64 of float32 RGBA rows, bottom row first.
window.renderGltf = async function (url, width, height, options) {
    const canvas = document.createElement("canvas");
    canvas.width = width;
    canvas.height = height;
    const gl = canvas.getContext("webgl2", {antialias: false});
    if (!gl) throw new Error("no WebGL2 context");
    const view = new GltfView(gl);
    const loader = view.createResourceLoader(NO_DRACO, undefined, LIBS);
    const state = view.createState();
    state.gltf = await loader.loadGltf(url);
    // It needs an environment even with image-based lighting off: a black one.
    state.environment = await loader.loadEnvironment(options.environment,
                                                     {lut_sheen_E_file: options.sheenLut});
    Object.assign(state.renderingParameters, {
        useIBL: false,
        usePunctual: true,
        toneMap: GltfState.ToneMaps.NONE,
        exposure: 1.0,
        clearColor: [0, 0, 0, 0],  // alpha 0: the background is told apart by alpha
        renderEnvironmentMap: false,
        useDirectionalLightsWithDisabledIBL: false,
    });
    state.sceneIndex = state.gltf.scene ?? 0;
    if (options.camera) {
        useGivenCamera(state, options.camera);
    } else {
        state.cameraIndex = firstCameraIndex(state.gltf);
        if (state.cameraIndex === undefined) throw new Error("the asset has no camera and none was given");
    }
    if (options.light) useGivenLight(view, state, options.light);

    const target = floatFramebuffer(gl, width, height);
    const restore = redirectDefaultFramebuffer(gl, target.framebuffer);
    try {
        // Twice: the first frame also uploads textures and compiles shaders.
        view.renderFrame(state, width, height);
        view.renderFrame(state, width, height);
    } finally {
        restore();
    }
    const pixels = new Float32Array(width * height * 4);
    gl.bindFramebuffer(gl.FRAMEBUFFER, target.framebuffer);
    gl.readPixels(0, 0, width, height, gl.RGBA, gl.FLOAT, pixels);
    const error = gl.getError();
    if (error !== gl.NO_ERROR) throw new Error(`WebGL error ${error}`);
    return {width, height, format: target.format, rgba: base64(new Uint8Array(pixels.buffer))};
};
window.rendererReady = true;

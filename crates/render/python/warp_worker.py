# The batch render worker of `--renderer warp`: MuJoCo Warp's ray tracer, driven by
# dexjoco-data over this process's stdin/stdout. Shipped inside the binary and run as
# `python -c`; needs mujoco==3.17.0, mujoco-warp==3.17.0, warp-lang==1.19.0.
#
# Framing: every message is a 12-byte header (u32 JSON length, u64 payload length, little
# endian), the JSON object, then the payload bytes. The Rust side (crates/render/src/warp/worker.rs)
# documents the requests; in short:
#   hello  -> versions and the device
#   open   -> compiles the scene with one extra camera per field of view asked for (the
#             view slots) and one extra directional light (the headlight, so its colours
#             can differ per world), allocates `worlds` worlds and a render context per
#             slot (supersampling needs each camera's rays precomputed)
#   render -> one slot; per-frame geom poses, per-world camera pose, lights and table
#             look; answers RGB (packed 0xAARRGGBB, rows top to bottom) and depth
#             (metres) per world
# Each world renders one image: worlds = frames x replays, one camera per call.
import json
import struct
import sys
import time

HEADER = struct.Struct("<IQ")
MAX_JSON = 1 << 24


def read_exact(stream, n):
    buf = bytearray()
    while len(buf) < n:
        chunk = stream.read(n - len(buf))
        if not chunk:
            raise EOFError("dexjoco-data closed the pipe")
        buf += chunk
    return bytes(buf)


def receive(stream):
    head = stream.read(HEADER.size)
    if not head:
        return None, None
    if len(head) < HEADER.size:
        head += read_exact(stream, HEADER.size - len(head))
    json_len, payload_len = HEADER.unpack(head)
    if json_len > MAX_JSON:
        raise ValueError(f"request header of {json_len} bytes")
    request = json.loads(read_exact(stream, json_len))
    return request, read_exact(stream, payload_len)


def send(stream, obj, payload=b""):
    body = json.dumps(obj).encode()
    stream.write(HEADER.pack(len(body), len(payload)))
    stream.write(body)
    if payload:
        stream.write(payload)
    stream.flush()


def versions():
    import importlib.metadata as md

    out = {"python": sys.version.split()[0]}
    for dist in ("mujoco", "mujoco-warp", "warp-lang"):
        try:
            out[dist] = md.version(dist)
        except md.PackageNotFoundError:
            out[dist] = None
    return out


class Worker:
    def __init__(self):
        self.scene = None

    def hello(self, req, _payload):
        import warp as wp

        wp.config.quiet = True
        wp.init()
        device = self.pick_device(req.get("device", "auto"))
        name = wp.get_device(device).name if device != "cpu" else "cpu"
        return {"versions": versions(), "device": device, "device_name": name}, b""

    @staticmethod
    def pick_device(asked):
        import warp as wp

        if asked == "auto":
            return "cuda:0" if wp.is_cuda_available() else "cpu"
        if asked.startswith("cuda") and not wp.is_cuda_available():
            raise RuntimeError(f"device '{asked}' asked for, but Warp sees no CUDA device")
        return asked

    def open(self, req, _payload):
        self.scene = Scene(req, self.pick_device(req.get("device", "auto")))
        return self.scene.describe(), b""

    def render(self, req, payload):
        if self.scene is None:
            raise RuntimeError("render before open")
        return self.scene.render(req, payload)


def compile_scene(req):
    import mujoco

    if "xml_path" in req:
        spec = mujoco.MjSpec.from_file(req["xml_path"])
    else:
        spec = mujoco.MjSpec.from_string(req["xml"])
    # The view camera and the headlight live on a body of their own, the last one, so
    # every id the scene's own model has stays what dexjoco-data knows.
    body = spec.worldbody.add_body(name="dexjoco_render")
    for k, fovy in enumerate(req["slots"]):
        body.add_camera(name=f"dexjoco_view_{k}", fovy=float(fovy))
    body.add_light(
        name="dexjoco_headlight",
        type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
        castshadow=False,
    )
    spec.visual.headlight.active = 0
    mjm = spec.compile()
    # Rendering only: solver settings MuJoCo Warp lacks do not matter here.
    mjm.opt.solver = mujoco.mjtSolver.mjSOL_NEWTON
    if mjm.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST:
        mjm.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
    return mjm


class Scene:
    BATCHED = ("geom_matid", "geom_rgba", "light_diffuse", "light_ambient", "light_specular")

    def __init__(self, req, device):
        import mujoco
        import mujoco_warp as mjw
        import numpy as np
        import warp as wp

        started = time.perf_counter()
        self.np, self.wp = np, wp
        mjm = compile_scene(req)
        self.ngeom, self.nlight = mjm.ngeom, mjm.nlight - 1
        self.cams = [mjm.camera(f"dexjoco_view_{k}").id for k in range(len(req["slots"]))]
        self.headlight = mjm.light("dexjoco_headlight").id
        expect = req["expect"]
        got = {"ngeom": mjm.ngeom, "nlight": self.nlight, "nmat": mjm.nmat}
        if any(expect[k] != v for k, v in got.items()):
            raise RuntimeError(f"the scene compiled here differs from dexjoco-data's: {got} vs {expect}")
        self.width, self.height = req["width"], req["height"]
        self.depth = bool(req.get("depth", False))
        self.worlds = int(req["worlds"])
        n = self.worlds
        with wp.ScopedDevice(device):
            mjd = mujoco.MjData(mjm)
            mujoco.mj_forward(mjm, mjd)
            self.m = mjw.put_model(mjm, batch_sizes={k: n for k in self.BATCHED})
            self.d = mjw.put_data(mjm, mjd, nworld=n)
            self.rcs = [
                mjw.create_render_context(
                    mjm,
                    nworld=n,
                    cam_res=(self.width, self.height),
                    render_rgb=True,
                    render_depth=self.depth,
                    cam_active=[cam],
                    use_textures=True,
                    use_shadows=bool(req.get("shadows", False)),
                    render_skybox=bool(req.get("skybox", False)),
                    samples_per_pixel=int(req.get("samples_per_pixel", 1)),
                    background_color=(0.0, 0.0, 0.0, 1.0),
                )
                for cam in self.cams
            ]
        self.device = device
        self.base = {k: getattr(self.m, k).numpy().copy() for k in self.BATCHED}
        self.headlight_specular = np.array(mjm.vis.headlight.specular, dtype=np.float32)
        self.open_seconds = time.perf_counter() - started

    def describe(self):
        return {
            "device": self.device,
            "worlds": self.worlds,
            "ngeom": self.ngeom,
            "nlight": self.nlight,
            "open_seconds": self.open_seconds,
        }

    def take(self, payload, offset, dtype, count):
        arr = self.np.frombuffer(payload, dtype=dtype, count=count, offset=offset)
        return arr, offset + arr.nbytes

    def unpack(self, req, payload):
        np = self.np
        f, w, g, nl = req["frames"], req["worlds"], self.ngeom, self.nlight
        if not 0 < w <= self.worlds:
            raise ValueError(f"{w} worlds in a batch; the context holds {self.worlds}")
        fields = [
            ("geom_xpos", np.float32, f * g * 3),
            ("geom_xmat", np.float32, f * g * 9),
            ("frame", np.int32, w),
            ("cam_xpos", np.float32, w * 3),
            ("cam_xmat", np.float32, w * 9),
            ("light_xpos", np.float32, w * nl * 3),
            ("light_xdir", np.float32, w * nl * 3),
            ("light_diffuse", np.float32, w * nl * 3),
            ("head_ambient", np.float32, w * 3),
            ("head_diffuse", np.float32, w * 3),
            ("table_matid", np.int32, w),
            ("table_rgba", np.float32, w * 4),
        ]
        need = sum(np.dtype(t).itemsize * c for _, t, c in fields)
        if need != len(payload):
            raise ValueError(f"render payload of {len(payload)} bytes, expected {need}")
        out, off = {}, 0
        for name, dtype, count in fields:
            out[name], off = self.take(payload, off, dtype, count)
        if f < 1 or out["frame"].min() < 0 or out["frame"].max() >= f:
            raise ValueError("a world names a frame outside the batch")
        return out

    def render(self, req, payload):
        import mujoco_warp as mjw

        np, wp = self.np, self.wp
        t0 = time.perf_counter()
        a = self.unpack(req, payload)
        f, w, n, g, nl = req["frames"], req["worlds"], self.worlds, self.ngeom, self.nlight
        table = int(req["table_geom"])
        slot = int(req["slot"])
        if not 0 <= slot < len(self.cams):
            raise ValueError(f"view slot {slot}; the scene was opened with {len(self.cams)}")
        cam, rc = self.cams[slot], self.rcs[slot]
        # Pad the batch with copies of its first world.
        idx = np.concatenate([np.arange(w), np.zeros(n - w, dtype=np.int64)])
        frame = a["frame"][idx]
        geom_xpos = a["geom_xpos"].reshape(f, g, 3)[frame]
        geom_xmat = a["geom_xmat"].reshape(f, g, 3, 3)[frame]
        cam_xpos = self.base_cams(cam, a["cam_xpos"].reshape(w, 3)[idx], 3)
        cam_xmat = self.base_cams(cam, a["cam_xmat"].reshape(w, 3, 3)[idx], (3, 3))
        lights = nl + 1
        light_xpos = np.zeros((n, lights, 3), np.float32)
        light_xdir = np.zeros((n, lights, 3), np.float32)
        light_xpos[:, :nl] = a["light_xpos"].reshape(w, nl, 3)[idx]
        light_xdir[:, :nl] = a["light_xdir"].reshape(w, nl, 3)[idx]
        # The headlight: at the camera, along its view (-z), as MuJoCo's.
        light_xpos[:, nl] = cam_xpos[:, cam]
        light_xdir[:, nl] = -cam_xmat[:, cam, :, 2]
        diffuse = self.base["light_diffuse"].copy()
        ambient = self.base["light_ambient"].copy()
        specular = self.base["light_specular"].copy()
        diffuse[:, :nl] = a["light_diffuse"].reshape(w, nl, 3)[idx]
        diffuse[:, nl] = a["head_diffuse"].reshape(w, 3)[idx]
        ambient[:, nl] = a["head_ambient"].reshape(w, 3)[idx]
        specular[:, nl] = self.headlight_specular
        matid = self.base["geom_matid"].copy()
        rgba = self.base["geom_rgba"].copy()
        matid[:, table] = a["table_matid"][idx]
        rgba[:, table] = a["table_rgba"].reshape(w, 4)[idx]
        t1 = time.perf_counter()
        with wp.ScopedDevice(self.device):
            d, m = self.d, self.m
            d.geom_xpos.assign(geom_xpos)
            d.geom_xmat.assign(geom_xmat)
            d.cam_xpos.assign(cam_xpos)
            d.cam_xmat.assign(cam_xmat)
            d.light_xpos.assign(light_xpos)
            d.light_xdir.assign(light_xdir)
            m.light_diffuse.assign(diffuse)
            m.light_ambient.assign(ambient)
            m.light_specular.assign(specular)
            m.geom_matid.assign(matid)
            m.geom_rgba.assign(rgba)
            wp.synchronize()
            t2 = time.perf_counter()
            mjw.refit_bvh(m, d, rc)
            mjw.render(m, d, rc)
            wp.synchronize()
            t3 = time.perf_counter()
            pixels = self.width * self.height
            rgb = rc.rgb_data.numpy()[:w, :pixels]
            out = [rgb.astype("<u4", copy=False).tobytes()]
            if self.depth:
                out.append(rc.depth_data.numpy()[:w, :pixels].astype("<f4", copy=False).tobytes())
        t4 = time.perf_counter()
        times = {"upload": t2 - t1 + (t1 - t0), "render": t3 - t2, "readback": t4 - t3}
        return {"worlds": w, "times": times}, b"".join(out)

    def base_cams(self, cam, view, shape):
        """The scene's camera array for every world, the view camera's entry replaced."""
        np = self.np
        n = self.worlds
        ncam = self.d.cam_xpos.shape[1]
        full = np.zeros((n, ncam) + ((shape,) if isinstance(shape, int) else shape), np.float32)
        full[:, cam] = view
        return full


def main():
    stdin, stdout = sys.stdin.buffer, sys.stdout.buffer
    # Everything else printed (Warp's messages) goes to stderr, never into the protocol.
    sys.stdout = sys.stderr
    worker = Worker()
    while True:
        req, payload = receive(stdin)
        if req is None:
            return
        op = req.get("op")
        try:
            handler = {"hello": worker.hello, "open": worker.open, "render": worker.render}[op]
            reply, data = handler(req, payload)
            reply["ok"] = True
            send(stdout, reply, data)
        except Exception as e:  # noqa: BLE001 - every failure goes back to the caller
            import traceback

            send(stdout, {"ok": False, "error": f"{type(e).__name__}: {e}", "trace": traceback.format_exc()})


main()

"""crease.py: crease's frame-by-frame garment runtime from Python, through ctypes and numpy.

    import numpy as np, crease
    with crease.SwingarRuntime("model.safetensors", "dress.obj", body="normal") as rt:
    # or crease.EpnetRuntime("epnet_model_dir") (the model's own garment)
        for pose, root in zip(poses, trans):          # (22,3) axis-angles, rad; (3,) m
            verts = rt.step(pose, root)              # (V,3) float32 world positions, m
    faces = rt.triangles                            # (F,3) int32, the garment's rest triangles

    with crease.GdsrRuntime("model.safetensors", "dataset", garment="tshirt") as rt:
        high = rt.step(low, body)      # (Vl,3) low simulation, (Vb,3) posed body -> (Vh,3)

The library is libcrease_runtime.so (built beside libcrease.a; `make build` puts it in
build/release). It is looked up in $CREASE_LIBRARY, then in ../build/release beside this file,
then by the system's loader. Errors raise crease.Error with the library's message, which
names the file or argument at fault. Only numpy and the standard library are used.
"""

import ctypes
import ctypes.util
import os

import numpy as np

__all__ = ["Error", "EpnetRuntime", "GdsrRuntime", "SwingarRuntime", "library"]

NJOINTS = 22


class Error(RuntimeError):
    """A crease call failed; the message is the library's."""


class _CrError(ctypes.Structure):
    _fields_ = [
        ("status", ctypes.c_int),
        ("src_file", ctypes.c_char_p),
        ("src_line", ctypes.c_int),
        ("msg", ctypes.c_char * 512),
    ]


class _CrMesh(ctypes.Structure):  # the leading fields of cr_mesh (crease/mesh.h)
    _fields_ = [
        ("nv", ctypes.c_int32),
        ("nf", ctypes.c_int32),
        ("nuv", ctypes.c_int32),
        ("pos", ctypes.POINTER(ctypes.c_float)),
        ("tri", ctypes.POINTER(ctypes.c_int32)),
    ]


_lib = None


def library():
    """The loaded libcrease_runtime.so (loaded on first use)."""
    global _lib
    if _lib is not None:
        return _lib
    here = os.path.dirname(os.path.abspath(__file__))
    candidates = [
        os.environ.get("CREASE_LIBRARY"),
        os.path.join(here, "..", "build", "release", "libcrease_runtime.so"),
        ctypes.util.find_library("crease_runtime"),
    ]
    tried = []
    for path in candidates:
        if not path:
            continue
        if os.sep in path and not os.path.exists(path):
            tried.append(path + " (missing)")
            continue
        try:
            lib = ctypes.CDLL(path)
            break
        except OSError as e:
            tried.append("%s (%s)" % (path, e))
    else:
        raise Error("crease: libcrease_runtime.so not found; set CREASE_LIBRARY (tried: %s)"
                    % "; ".join(tried))
    f = ctypes.c_float
    P = ctypes.POINTER
    vp = ctypes.c_void_p
    err = P(_CrError)
    for method in ("swingar", "epnet", "gdsr"):
        fn = lambda name: getattr(lib, "cr_%s_runtime_%s" % (method, name))
        fn("step").argtypes = [vp, P(f), P(f), P(f), err]
        if method == "gdsr":
            fn("step_batch").argtypes = [P(vp), ctypes.c_int32, P(P(f)), P(P(f)), P(P(f)), err]
        else:
            fn("step_batch").argtypes = [P(vp), ctypes.c_int32, P(f), P(f), P(P(f)), err]
        for name, res in (("reset", None), ("destroy", None), ("vertices", ctypes.c_int32),
                          ("rest", P(_CrMesh))):
            fn(name).argtypes = [vp]
            fn(name).restype = res
    lib.cr_swingar_runtime_open.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_char_p,
                                            ctypes.c_size_t, P(vp), err]
    lib.cr_swingar_runtime_arena_bytes.argtypes = [vp]
    lib.cr_swingar_runtime_arena_bytes.restype = ctypes.c_size_t
    lib.cr_epnet_runtime_open.argtypes = [ctypes.c_char_p, ctypes.c_char_p, vp, P(vp), err]
    lib.cr_epnet_runtime_rb.argtypes = [vp]
    lib.cr_epnet_runtime_rb.restype = P(f)
    lib.cr_epnet_runtime_hinges.argtypes = [vp]
    lib.cr_epnet_runtime_hinges.restype = ctypes.c_int32
    lib.cr_gdsr_runtime_open.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_char_p,
                                         ctypes.c_char_p, vp, P(vp), err]
    for name in ("low_vertices", "body_vertices"):
        getattr(lib, "cr_gdsr_runtime_" + name).argtypes = [vp]
        getattr(lib, "cr_gdsr_runtime_" + name).restype = ctypes.c_int32
    lib.cr_gdsr_runtime_raw.argtypes = [vp]
    lib.cr_gdsr_runtime_raw.restype = P(f)
    lib.cr_gdsr_runtime_arena_bytes.argtypes = [vp]
    lib.cr_gdsr_runtime_arena_bytes.restype = ctypes.c_size_t
    _lib = lib
    return lib


def _fptr(a):
    return a.ctypes.data_as(ctypes.POINTER(ctypes.c_float))


def _check(status, err):
    if status != 0:
        raise Error(err.msg.decode("utf-8", "replace"))


def _floats(a, shape, what):
    a = np.ascontiguousarray(a, dtype=np.float32)
    if a.shape != shape and a.size == int(np.prod(shape)):
        a = a.reshape(shape)
    if a.shape != shape:
        raise Error("crease: %s has shape %s, expected %s" % (what, a.shape, shape))
    return a


class _Runtime:
    """What every method's runtime shares: step, step_batch, reset, close, the garment's
    rest mesh (triangles, rest) and its vertex count."""

    _method = None

    def _opened(self, lib, handle):
        self._lib, self._rt = lib, handle
        self._fn = lambda name: getattr(lib, "cr_%s_runtime_%s" % (self._method, name))
        self.vertices = self._fn("vertices")(self._rt)
        mesh = self._fn("rest")(self._rt).contents
        self.triangles = np.ctypeslib.as_array(mesh.tri, shape=(mesh.nf, 3)).copy()
        self.rest = np.ctypeslib.as_array(mesh.pos, shape=(mesh.nv, 3)).copy()

    def _step(self, a, b, out):
        """The method's step on two float32 arrays into out ((V,3), made when None)."""
        if out is None:
            out = np.empty((self.vertices, 3), dtype=np.float32)
        elif out.dtype != np.float32 or out.shape != (self.vertices, 3) or \
                not out.flags.c_contiguous:
            raise Error("crease: out must be a C-contiguous float32 array of shape (%d, 3)"
                        % self.vertices)
        err = _CrError()
        _check(self._fn("step")(self._rt, _fptr(a), _fptr(b), _fptr(out), ctypes.byref(err)),
               err)
        return out

    def step(self, pose, root, out=None):
        """One frame: pose (22,3) axis-angles (rad, SMPL's joint order, relative to the rest
        pose; 66 floats also do), root (3,) translation, m. Returns (V,3) float32 positions."""
        if not self._rt:
            raise Error("crease: the runtime is closed")
        return self._step(_floats(pose, (NJOINTS, 3), "pose"), _floats(root, (3,), "root"), out)

    def reset(self):
        """Back to before the first frame."""
        if self._rt:
            self._fn("reset")(self._rt)

    def close(self):
        if getattr(self, "_rt", None):
            self._fn("destroy")(self._rt)
            self._rt = ctypes.c_void_p()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __del__(self):
        self.close()

    @classmethod
    def step_batch(cls, runtimes, poses, roots):
        """One frame of several characters of this method in one call: poses (n,22,3),
        roots (n,3). Returns a list of (V_i,3) arrays."""
        n = len(runtimes)
        if n == 0:
            return []
        if any(not isinstance(r, cls) for r in runtimes):
            raise Error("crease: step_batch takes runtimes of one method")
        poses = _floats(poses, (n, NJOINTS, 3), "poses")
        roots = _floats(roots, (n, 3), "roots")
        outs = [np.empty((r.vertices, 3), dtype=np.float32) for r in runtimes]
        handles = (ctypes.c_void_p * n)(*[r._rt.value for r in runtimes])
        optrs = (ctypes.POINTER(ctypes.c_float) * n)(*[_fptr(o) for o in outs])
        err = _CrError()
        _check(runtimes[0]._fn("step_batch")(handles, n, _fptr(poses), _fptr(roots), optrs,
                                             ctypes.byref(err)), err)
        return outs


class SwingarRuntime(_Runtime):
    """SwinGar frame by frame (crease/swingar.h, cr_swingar_runtime_*).

    model: a model file from `crease swingar train`; garment: an OBJ, PLY or glb garment
    (UVs not needed), fitted to the body first; body: a mannequin preset (slim, normal,
    heavy) or an SMPL-family FILE.npz[:betas]. All memory is taken here; step allocates only
    the returned array (pass out= to reuse one)."""

    _method = "swingar"

    def __init__(self, model, garment, body="normal"):
        lib = library()
        rt = ctypes.c_void_p()
        err = _CrError()
        _check(lib.cr_swingar_runtime_open(os.fsencode(model), os.fsencode(garment),
                                           body.encode() if body else None, 0,
                                           ctypes.byref(rt), ctypes.byref(err)), err)
        self._opened(lib, rt)
        self.arena_bytes = lib.cr_swingar_runtime_arena_bytes(rt)


class EpnetRuntime(_Runtime):
    """EPNet's proxy inference frame by frame (crease/epnet.h, cr_epnet_runtime_*).

    model_dir: a folder from `crease epnet train` (its garment is the model's); body: a body
    spec, or None for the model's. rb() is the rest bending angle per hinge after the last
    frame (rad)."""

    _method = "epnet"

    def __init__(self, model_dir, body=None):
        lib = library()
        rt = ctypes.c_void_p()
        err = _CrError()
        _check(lib.cr_epnet_runtime_open(os.fsencode(model_dir), body.encode() if body else None,
                                         None, ctypes.byref(rt), ctypes.byref(err)), err)
        self._opened(lib, rt)
        self.hinges = lib.cr_epnet_runtime_hinges(rt)

    def rb(self):
        p = self._lib.cr_epnet_runtime_rb(self._rt)
        return np.ctypeslib.as_array(p, shape=(self.hinges,)).copy()


class GdsrRuntime(_Runtime):
    """gdsr frame by frame (crease/gdsr.h, cr_gdsr_runtime_*): a low-resolution garment
    simulation and the posed body in, the high-resolution garment out.

    model: a model file from `crease gdsr train`; dataset: a `crease dataset` folder with the
    low and high `garment` on `body` (`--res low,high`), whose pair and rest body the model
    runs on. step(low, body) takes the frame's low garment (Vl,3) and posed body (Vb,3), m, and
    returns (V,3) float32 (V the high garment's), after the collision handling of `gdsr run`;
    raw() is the last frame's output before it. All memory is taken here."""

    _method = "gdsr"

    def __init__(self, model, dataset, garment="tshirt", body="normal"):
        lib = library()
        rt = ctypes.c_void_p()
        err = _CrError()
        _check(lib.cr_gdsr_runtime_open(os.fsencode(model), os.fsencode(dataset),
                                        garment.encode() if garment else None,
                                        body.encode() if body else None, None,
                                        ctypes.byref(rt), ctypes.byref(err)), err)
        self._opened(lib, rt)
        self.low_vertices = lib.cr_gdsr_runtime_low_vertices(rt)
        self.body_vertices = lib.cr_gdsr_runtime_body_vertices(rt)
        self.arena_bytes = lib.cr_gdsr_runtime_arena_bytes(rt)

    def step(self, low, body, out=None):
        """One frame: low (Vl,3) the low garment, body (Vb,3) the posed body, m. Returns (V,3)
        float32 positions of the high garment, m."""
        if not self._rt:
            raise Error("crease: the runtime is closed")
        return self._step(_floats(low, (self.low_vertices, 3), "low"),
                          _floats(body, (self.body_vertices, 3), "body"), out)

    def raw(self):
        """The last frame's output before the collision handling, (V,3) float32."""
        p = self._lib.cr_gdsr_runtime_raw(self._rt)
        return np.ctypeslib.as_array(p, shape=(self.vertices, 3)).copy()

    @classmethod
    def step_batch(cls, runtimes, lows, bodies):
        """One frame of several characters in one call: lows[i] (Vl_i,3), bodies[i] (Vb_i,3).
        Returns a list of (V_i,3) arrays."""
        n = len(runtimes)
        if n == 0:
            return []
        if any(not isinstance(r, cls) for r in runtimes) or len(lows) != n or len(bodies) != n:
            raise Error("crease: step_batch takes gdsr runtimes and one low and body each")
        lows = [_floats(a, (r.low_vertices, 3), "low") for r, a in zip(runtimes, lows)]
        bodies = [_floats(a, (r.body_vertices, 3), "body") for r, a in zip(runtimes, bodies)]
        outs = [np.empty((r.vertices, 3), dtype=np.float32) for r in runtimes]
        FP = ctypes.POINTER(ctypes.c_float)
        handles = (ctypes.c_void_p * n)(*[r._rt.value for r in runtimes])
        lp = (FP * n)(*[_fptr(a) for a in lows])
        bp = (FP * n)(*[_fptr(a) for a in bodies])
        op = (FP * n)(*[_fptr(o) for o in outs])
        err = _CrError()
        _check(runtimes[0]._fn("step_batch")(handles, n, lp, bp, op, ctypes.byref(err)), err)
        return outs

"""One offscreen pyrender scene holding a single deforming mesh, drawn through EGL.

The scene, lights and the mesh's GPU buffers are made once; each frame only uploads new
vertex data, moves the camera and draws the window of the image around the mesh
(software GL pays for every pixel). Stages share one renderer; the last to close
releases the GL context.
"""

from __future__ import annotations

import os

import numpy as np

from rendering.camera import Camera

FLOATS_PER_VERTEX = 10  # position, normal, RGBA colour, as pyrender lays them out
WINDOW_STEP = 32  # window sizes are rounded up to this, so the framebuffer rarely changes


def _pyrender():
    """Import pyrender with offscreen EGL unless another platform was asked for."""
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    import pyrender

    return pyrender


def _light_pose(towards: np.ndarray) -> np.ndarray:
    """Return a node pose whose -z axis (where lights shine) points away from ``towards``."""
    z = towards / np.linalg.norm(towards)
    x = np.cross([0.0, 0.0, 1.0], z)
    if np.linalg.norm(x) < 1e-6:
        x = np.array([1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    pose = np.eye(4)
    pose[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
    return pose


# One offscreen renderer per process, shared by every stage: deleting a renderer
# terminates the EGL display, which would break any other renderer still in use.
_SHARED = {"renderer": None, "users": 0}


def _acquire_renderer():
    if _SHARED["renderer"] is None:
        _SHARED["renderer"] = _pyrender().OffscreenRenderer(WINDOW_STEP, WINDOW_STEP)
    _SHARED["users"] += 1
    return _SHARED["renderer"]


def _release_renderer() -> None:
    _SHARED["users"] -= 1
    if _SHARED["users"] == 0:
        _SHARED["renderer"].delete()
        _SHARED["renderer"] = None


class Stage:
    """Draw one mesh of fixed topology in new poses, returning premultiplied RGBA images.

    ``lights`` lists ``(direction towards the light, intensity)`` of directional lights;
    ``ambient`` is the light every surface gets. ``near`` and ``far`` clip the view.
    """

    def __init__(self, near: float, far: float, lights, ambient: float, roughness: float = 0.7):
        pyrender = _pyrender()
        self._pyrender = pyrender
        self._renderer = _acquire_renderer()
        self._scene = pyrender.Scene(bg_color=(0.0, 0.0, 0.0, 0.0), ambient_light=(ambient,) * 3)
        self._lens = pyrender.IntrinsicsCamera(1.0, 1.0, 0.0, 0.0, znear=near, zfar=far)
        self._camera = self._scene.add(self._lens)
        for towards, intensity in lights:
            light = pyrender.DirectionalLight(color=np.ones(3), intensity=intensity)
            self._scene.add(light, pose=_light_pose(np.asarray(towards, dtype=float)))
        self._material = pyrender.MetallicRoughnessMaterial(
            baseColorFactor=(1.0, 1.0, 1.0, 1.0), metallicFactor=0.0, roughnessFactor=roughness
        )
        self._node = self._primitive = self._buffer = None

    def show(self, faces: np.ndarray, colours: np.ndarray) -> None:
        """Put a mesh of faces ``(F, 3)`` and linear RGBA vertex colours ``(V, 4)`` on stage."""
        pyrender = self._pyrender
        if self._node is not None:
            self._scene.remove_node(self._node)
        count = len(colours)
        primitive = pyrender.Primitive(
            positions=np.zeros((count, 3), np.float32),
            normals=np.tile(np.float32([0.0, 0.0, 1.0]), (count, 1)),
            color_0=np.asarray(colours, np.float32),
            indices=np.asarray(faces, np.uint32),
            material=self._material,
        )
        self._node = self._scene.add(pyrender.Mesh([primitive]))
        self._primitive = primitive
        self._buffer = np.empty((count, FLOATS_PER_VERTEX), np.float32)
        self._buffer[:, 6:] = colours

    def window(self, pixels: np.ndarray, width: int, height: int):
        """Return the window ``(left, top, right, bottom)`` of an image to draw these pixels.

        It covers the pixels ``(N, 2)`` with a margin, has a size rounded up to
        ``WINDOW_STEP`` and stays inside the image; ``None`` if they are all outside.
        """
        low = np.floor(pixels.min(axis=0)).astype(int) - 2
        high = np.ceil(pixels.max(axis=0)).astype(int) + 2
        if (high <= 0).any() or low[0] >= width or low[1] >= height:
            return None
        box = []
        for start, end, limit in ((low[0], high[0], width), (low[1], high[1], height)):
            start, end = max(start, 0), min(end, limit)
            size = min(-(-(end - start) // WINDOW_STEP) * WINDOW_STEP, limit)
            start = min(start, limit - size)
            box.append((start, start + size))
        (left, right), (top, bottom) = box
        return left, top, right, bottom

    def draw(self, vertices: np.ndarray, normals: np.ndarray, camera: Camera, box) -> np.ndarray:
        """Return the window ``box`` of the mesh seen by ``camera``, premultiplied RGBA."""
        from OpenGL import GL

        if camera.orthographic:
            raise ValueError("the stage draws perspective views only")
        self._buffer[:, :3] = vertices
        self._buffer[:, 3:6] = normals
        left, top, right, bottom = box
        self._renderer.viewport_width = right - left
        self._renderer.viewport_height = bottom - top
        self._lens.fx = self._lens.fy = camera.focal
        self._lens.cx = camera.width / 2 - left
        self._lens.cy = camera.height / 2 - top
        pose = np.eye(4)
        right_axis, down, forward = camera.rotation
        pose[:3, :3] = np.stack([right_axis, -down, -forward], axis=1)
        pose[:3, 3] = camera.eye
        self._scene.set_pose(self._camera, pose)
        self._renderer._platform.make_current()  # the buffer below lives in its context
        if self._primitive._vaid is not None:
            # pyrender keeps a primitive's vertices in one interleaved buffer, its first;
            # overwriting it is far cheaper than a new mesh every frame.
            GL.glBindBuffer(GL.GL_ARRAY_BUFFER, self._primitive._buffers[0])
            GL.glBufferSubData(GL.GL_ARRAY_BUFFER, 0, self._buffer.nbytes, self._buffer)
            GL.glBindBuffer(GL.GL_ARRAY_BUFFER, 0)
        else:  # not yet uploaded: the first render sends these positions
            self._primitive.positions = self._buffer[:, :3].copy()
            self._primitive.normals = self._buffer[:, 3:6].copy()
        colour, _ = self._renderer.render(self._scene, self._pyrender.RenderFlags.RGBA)
        return colour

    def close(self) -> None:
        """Let go of the renderer; the last stage to close releases the GL context."""
        if self._renderer is not None:
            if self._node is not None:
                self._scene.remove_node(self._node)
                self._renderer.render(self._scene)  # frees the mesh's GL buffers
                self._node = None
            self._renderer = None
            _release_renderer()

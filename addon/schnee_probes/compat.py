"""Blender-version differences, in one place.

The add-on targets Debian's Blender 3.4 and is written so that Blender 4.x is a small step: every
API that moved between those versions is reached through a helper here, never directly.
"""
import bpy

BLENDER_VERSION = bpy.app.version


def set_equirectangular(camera_data):
    """Make ``camera_data`` a full-sphere equirectangular panorama camera (Cycles).

    Blender 3.x keeps the panorama settings on ``camera.data.cycles``; 4.0 moved them onto the
    camera datablock itself (``camera.data.panorama_type``, ``latitude_min``, ...).
    """
    camera_data.type = 'PANO'
    holder = camera_data if hasattr(camera_data, "panorama_type") else camera_data.cycles
    holder.panorama_type = 'EQUIRECTANGULAR'
    # Full sphere, whatever the defaults of a given version are (angles in radians).
    holder.latitude_min = -1.5707963267948966
    holder.latitude_max = 1.5707963267948966
    holder.longitude_min = -3.141592653589793
    holder.longitude_max = 3.141592653589793


def panorama_settings_holder(camera_data):
    """The struct that carries the panorama settings of ``camera_data`` in this Blender."""
    return camera_data if hasattr(camera_data, "panorama_type") else camera_data.cycles


def light_objects(scene):
    """Light objects of ``scene`` (type 'LIGHT')."""
    return [ob for ob in scene.objects if ob.type == 'LIGHT']


def has_visible_camera(ob):
    """Blender 3.0+ has per-object ``visible_camera``; 2.9x used ``cycles_visibility.camera``."""
    return hasattr(ob, "visible_camera")

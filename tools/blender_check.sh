#!/usr/bin/env bash
# Imports a GLB written by kslab into Blender (headless) and prints what Blender made of it:
# meshes, shape keys and actions (the goal: "imports in Blender with shape keys and an
# action"). Needs blender (apt-get install blender; checked with 3.4.1). Not part of CI (a
# 300 MB install). Usage:
#   kslab rig ../shared/data/pyfeat_samples/news_sample_compact.csv --gltf /tmp/rig.glb
#   tools/blender_check.sh /tmp/rig.glb
set -euo pipefail
glb=$(cd "$(dirname "$1")" && pwd)/$(basename "$1")
# Blender 3.4's glTF importer uses numpy.bool, which numpy 1.24 removed: alias it.
blender -b --python-expr "
import numpy
if not hasattr(numpy, 'bool'):
    numpy.bool = bool
import bpy
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath='$glb')
for o in bpy.context.scene.objects:
    sk = o.data.shape_keys if o.type == 'MESH' else None
    print('object', o.name, o.type, 'vertices', len(o.data.vertices) if o.type == 'MESH' else 0,
          'shape keys', len(sk.key_blocks) if sk else 0,
          'action', sk.animation_data.action.name if sk and sk.animation_data and sk.animation_data.action else None)
for a in bpy.data.actions:
    print('action', a.name, 'frames', tuple(a.frame_range), 'curves', len(a.fcurves))
" 2>&1 | grep -E '^(object|action)|Error'

"""Function-curve editor (paper §4.3 "Function Curves", §6.1, Fig. 10): a Maya/Blender-style graph editor.

The graph is a vertical plane in the 3D scene under ``root`` (a frame the app may move):
time runs along the frame's +x axis, values along +z, and the graph faces the frame's −y
side (a camera placed on −y looking toward +y sees it head-on; :meth:`CurveEditor.camera_pose`
computes such a pose). Geometry in the frame, in metres: the plot area is
``[0, width_m] × [0, height_m]``; tick labels sit left of and below it.

Editing goes through :class:`~studio.style_session.StyleSession` only. A knot drag applies
throttled previews (every :data:`PREVIEW_PERIOD_S`) so the engine follows the edit, then
collapses them into one undo entry at release (:class:`UndoGroup`, public session methods
only). Refused edits show the validator's message and snap back to the pre-drag style.

Mouse interactions (viser 1.1.1, verified in ``viser/_scene_handles.py`` / ``DragLayer.tsx``):
knots and tangent handles are icospheres/boxes with ``handle.on_drag`` (start/update/end,
~20 Hz; ``end_position`` is the pointer on a camera-parallel plane through the grab point —
the editor intersects the camera ray through it with the graph plane); click selects,
Ctrl/Cmd+click toggles; Shift+drag on the canvas draws a selection rectangle
(``scene.on_rect_select``; Ctrl/Cmd+Shift adds to the selection). Ctrl+Z / Ctrl+Shift+Z /
Ctrl+Y click the Undo/Redo buttons through a keydown listener installed by an ``add_html``
snippet (an ``<img onerror>`` handler: React's ``innerHTML`` never runs ``<script>`` tags).

The package's parts: ``editor`` (the panel, its public API, applying edits), ``graph_view``
(drawing), ``interaction`` (drags, clicks, undo grouping), ``widgets`` (the GUI folder),
``appearance`` (colours, ticks, projection), ``state`` (what the parts share). The editing rules
themselves (knot moves, tangents, limits, paste) live in :mod:`engine.gait.curve_editing`.
"""

from engine.gait.curve_editing import Clipboard, KnotRef
from studio.panels.curve_editor.appearance import nice_ticks, project_to_screen
from studio.panels.curve_editor.editor import CurveEditor
from studio.panels.curve_editor.interaction import UndoGroup

__all__ = ["Clipboard", "CurveEditor", "KnotRef", "UndoGroup", "nice_ticks", "project_to_screen"]

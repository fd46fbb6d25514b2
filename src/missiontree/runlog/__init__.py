"""See a run afterwards: replay of tick logs, the HTML viewer, and .btlog and MCAP exports.

- :mod:`~missiontree.runlog.replay`: one reader of tick logs (node states, blackboard, events at
  any tick) that the viewer and every export use.
- :mod:`~missiontree.runlog.record`: mission hooks writing ``runview.json`` (declared tree, map,
  trajectory) into the run directory.
- :mod:`~missiontree.runlog.html`: the self-contained HTML viewer; :mod:`~missiontree.runlog.follow`
  serves it live.
- :mod:`~missiontree.runlog.btlog` (Groot2) and :mod:`~missiontree.runlog.mcap_export` (Foxglove).
"""

"""Episode videos: ``multion eval --video N`` and ``multion video RUN_DIR --episode ID``.

Frames come from the recorded actions replayed in this process (:mod:`.recorded`), drawn by
:mod:`.frames` and encoded to H.264 MP4 by :mod:`.encoder`; :mod:`.film` puts them together.
"""

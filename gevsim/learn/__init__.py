"""Learned reconstruction (issue 38): a planar-scene training-set generator, one small recurrent network of
the FireNet/E2VID family with an input encoding per event type, its training (``gevsim train``, PyTorch, the
``[learn]`` extra) and its inference in numpy (the shipped weights run in the default install)."""

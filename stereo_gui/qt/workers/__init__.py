"""The threads that run the pipeline and other work off the UI thread: the frame worker, the
job runner, the generator job worker, the recorder."""

"""The QThreads that run the pipeline and other work off the UI thread: the frame worker, the
job runner, the generator job worker and the recorder, all on threads.WorkerThread."""

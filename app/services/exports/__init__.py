"""The exports as a whole, above every service whose rows they write: the registry of export formats (``formats``:
each format's name, choices, download and writers, from the database now or from a release) and the export job's
zip files (``files``). The writers themselves stay with what they write (``app.services.transfer``, ISSIA-3D in
``app.services.issia``, a release's documents in ``app.services.releases``)."""

"""What the pages and the stored reasons say, below every service that says it: the table of words for every code a
page shows (``words``, written to ``static/js/words.js``) and the sentences of doubts (``doubt_words``). The
calibration, the recomputation, the review loop and the imports read them; they read nothing of the services."""

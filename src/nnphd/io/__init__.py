"""Files out: JSON results and figures written atomically, the cache of resumable runs, the HTML renderer."""

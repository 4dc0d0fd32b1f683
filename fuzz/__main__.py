"""``python -m fuzz``: the fuzz harness's command line (:func:`fuzz.fuzz_readers.main`)."""
import sys

from fuzz.fuzz_readers import main

sys.exit(main())

"""python3 -m earshot dataset SPEC.json -o DIR [--workers N | --scheduler ADDR | --in-process]"""
import sys


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if not argv or argv[0] in ("-h", "--help"):
        print(__doc__.strip() + "\n\nCommands:\n  dataset   make (or resume) a dataset of IRs from a spec file\n"
              "\nThe engine's own command line is the `earshot` program.")
        return 0 if argv else 2
    if argv[0] == "dataset":
        from .dataset import main as dataset_main
        return dataset_main(argv[1:])
    print(f"python3 -m earshot: unknown command '{argv[0]}' (try: dataset)", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())

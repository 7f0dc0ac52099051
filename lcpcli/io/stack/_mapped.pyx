"""Read-only memory maps of input files whose truncation cannot kill the process.

A page of a shared file mapping that lies past the end of the file (the file was truncated
after it was mapped) raises SIGBUS in whichever thread touches it: a compiled solver thread,
the digest, numpy.  :class:`Mapping` registers each map with one process-wide SIGBUS handler
(``sigaction``, ``SA_SIGINFO``).  On a fault inside a registered map the handler replaces
the map from the faulting page to its end with anonymous zero pages (``mmap`` with
``MAP_FIXED``), records that page (:meth:`Mapping.lost`, the lowest replaced offset) and
returns: the faulting load runs again and reads zeros, in any thread, with no jump out of
compiled code.  The reader that made the map then refuses the data read from it
(:meth:`lcpcli.io.stack.mapped.MappedStack.check`).  A SIGBUS anywhere else (or one sent by
another process) gets the action that was in place before the handler, as if it were never
installed.  POSIX systems with ``MAP_FIXED`` and ``si_addr`` (Linux, macOS); on Windows no map
is made (:class:`Mapping` raises OSError: every chunk is copied).
"""

from cpython.buffer cimport PyBUF_WRITABLE
from libc.stdint cimport uintptr_t


cdef extern from *:
    """
    #include <errno.h>
    #include <stdint.h>
    #include <string.h>
    #define LCPCLI_MAP_SLOTS 256

    #ifdef _WIN32
    /* no guarded maps: Mapping refuses, every chunk is copied */
    static int lcpcli_install_bus(void) { return ENOSYS; }
    static int lcpcli_bus_is_ours(void) { return 0; }
    static int lcpcli_register(uintptr_t start, uintptr_t end) { return -1; }
    static void lcpcli_unregister(int i) {}
    static uintptr_t lcpcli_lost(int i) { return UINTPTR_MAX; }
    static uintptr_t lcpcli_faults(int i) { return 0; }
    static void *lcpcli_map(int fd, size_t length) { return NULL; }
    static int lcpcli_populate(void *base, size_t offset, size_t length) { return ENOSYS; }
    static int lcpcli_unmap(void *addr, size_t length) { return 0; }
    #else
    #include <signal.h>
    #include <sys/mman.h>
    #include <unistd.h>

    #ifndef MADV_POPULATE_READ
    #define MADV_POPULATE_READ 22
    #endif
    #ifndef MAP_ANONYMOUS
    #define MAP_ANONYMOUS MAP_ANON
    #endif

    typedef struct {
        uintptr_t start, end;  /* the map's pages, [start, end) */
        uintptr_t lost;        /* lowest offset replaced by zeros, or UINTPTR_MAX */
        uintptr_t faults;      /* SIGBUS faults taken in the map */
        int used;
    } lcpcli_map_slot;

    static lcpcli_map_slot lcpcli_slots[LCPCLI_MAP_SLOTS];
    static struct sigaction lcpcli_previous_bus;
    static int lcpcli_bus_installed = 0;
    static uintptr_t lcpcli_page_size = 4096;  /* set by lcpcli_install_bus */

    static void lcpcli_on_bus(int sig, siginfo_t *si, void *ctx) {
        (void)sig; (void)ctx;
        if (si != NULL && si->si_code > 0) {  /* a fault, not a signal sent by kill */
            uintptr_t a = (uintptr_t)si->si_addr;
            uintptr_t page_size = lcpcli_page_size;
            int i;
            for (i = 0; i < LCPCLI_MAP_SLOTS; i++) {
                lcpcli_map_slot *s = &lcpcli_slots[i];
                if (!__atomic_load_n(&s->used, __ATOMIC_ACQUIRE)) continue;
                if (a < s->start || a >= s->end) continue;
                uintptr_t page = a & ~(page_size - 1);
                int saved = errno;
                void *r = mmap((void *)page, s->end - page, PROT_READ,
                               MAP_PRIVATE | MAP_ANONYMOUS | MAP_FIXED, -1, 0);
                errno = saved;
                if (r == MAP_FAILED) break;
                __atomic_add_fetch(&s->faults, 1, __ATOMIC_ACQ_REL);
                uintptr_t off = page - s->start;
                uintptr_t cur = __atomic_load_n(&s->lost, __ATOMIC_ACQUIRE);
                while (off < cur && !__atomic_compare_exchange_n(
                           &s->lost, &cur, off, 0, __ATOMIC_ACQ_REL, __ATOMIC_ACQUIRE)) {}
                return;  /* the load runs again, on zeros */
            }
        }
        /* not ours: the previous action (the fault happens again, or the signal is raised
           again once this handler returns) */
        sigaction(SIGBUS, &lcpcli_previous_bus, NULL);
        if (si == NULL || si->si_code <= 0) raise(SIGBUS);
    }

    static int lcpcli_install_bus(void) {
        struct sigaction sa;
        if (lcpcli_bus_installed) return 0;
        lcpcli_page_size = (uintptr_t)sysconf(_SC_PAGESIZE);
        memset(&sa, 0, sizeof sa);
        sa.sa_sigaction = lcpcli_on_bus;
        sa.sa_flags = SA_SIGINFO | SA_RESTART;
        sigemptyset(&sa.sa_mask);
        if (sigaction(SIGBUS, &sa, &lcpcli_previous_bus) != 0) return errno;
        lcpcli_bus_installed = 1;
        return 0;
    }

    static int lcpcli_bus_is_ours(void) {
        struct sigaction now;
        if (sigaction(SIGBUS, NULL, &now) != 0) return 0;
        return (now.sa_flags & SA_SIGINFO) && now.sa_sigaction == lcpcli_on_bus;
    }

    /* a free slot for [start, end), or -1 */
    static int lcpcli_register(uintptr_t start, uintptr_t end) {
        int i;
        for (i = 0; i < LCPCLI_MAP_SLOTS; i++) {
            lcpcli_map_slot *s = &lcpcli_slots[i];
            if (__atomic_load_n(&s->used, __ATOMIC_ACQUIRE)) continue;
            s->start = start; s->end = end;
            __atomic_store_n(&s->lost, UINTPTR_MAX, __ATOMIC_RELEASE);
            __atomic_store_n(&s->faults, 0, __ATOMIC_RELEASE);
            __atomic_store_n(&s->used, 1, __ATOMIC_RELEASE);
            return i;
        }
        return -1;
    }

    static void lcpcli_unregister(int i) {
        __atomic_store_n(&lcpcli_slots[i].used, 0, __ATOMIC_RELEASE);
    }

    static uintptr_t lcpcli_lost(int i) {
        return __atomic_load_n(&lcpcli_slots[i].lost, __ATOMIC_ACQUIRE);
    }

    static uintptr_t lcpcli_faults(int i) {
        return __atomic_load_n(&lcpcli_slots[i].faults, __ATOMIC_ACQUIRE);
    }

    static void *lcpcli_map(int fd, size_t length) {
        void *p = mmap(NULL, length, PROT_READ, MAP_SHARED, fd, 0);
        return p == MAP_FAILED ? NULL : p;
    }

    /* the pages of [p, p + length) mapped now (read from the file where needed): 0, or an
       errno (EINVAL where the system has no MADV_POPULATE_READ: then MADV_WILLNEED) */
    static int lcpcli_populate(void *base, size_t offset, size_t length) {
        uintptr_t a = ((uintptr_t)base + offset) & ~(lcpcli_page_size - 1);
        uintptr_t b = (uintptr_t)base + offset + length;
        int r;
        if (length == 0) return 0;
        r = madvise((void *)a, b - a, MADV_POPULATE_READ);
        if (r != 0 && errno == EINVAL) r = madvise((void *)a, b - a, MADV_WILLNEED);
        return r == 0 ? 0 : errno;
    }

    static int lcpcli_unmap(void *addr, size_t length) { return munmap(addr, length); }
    #endif
    """
    int LCPCLI_MAP_SLOTS
    int lcpcli_install_bus()
    int lcpcli_bus_is_ours()
    int lcpcli_register(uintptr_t start, uintptr_t end)
    void lcpcli_unregister(int i)
    uintptr_t lcpcli_lost(int i)
    uintptr_t lcpcli_faults(int i)
    void *lcpcli_map(int fd, size_t length)
    int lcpcli_populate(void *base, size_t offset, size_t length) nogil
    int lcpcli_unmap(void *addr, size_t length)


def install() -> None:
    """Install the SIGBUS handler (once per process; OSError when the system refuses)."""
    cdef int err = lcpcli_install_bus()
    if err:
        raise OSError(err, "sigaction(SIGBUS) failed")


def installed() -> bool:
    """Whether SIGBUS goes to this module's handler now (another library may have replaced
    it since: then a map is no longer guarded, and :class:`Mapping` refuses to make one)."""
    return bool(lcpcli_bus_is_ours())


cdef class Mapping:
    """``length`` bytes of the open file ``fd`` from its start, mapped read-only and shared
    (the page cache itself, no copy), guarded (module docstring).  A read-only buffer of
    bytes; numpy views of it keep it alive.  The map is removed when the last reference
    goes.  OSError when the system refuses the map or the handler, or when
    ``LCPCLI_MAP_SLOTS`` maps are alive already."""

    cdef void *base
    cdef size_t length
    cdef int slot
    cdef Py_ssize_t shape[1]
    cdef Py_ssize_t strides[1]

    def __cinit__(self, int fd, size_t length):
        self.base, self.slot = NULL, -1
        if length == 0:
            raise OSError(0, "an empty file is not mapped")
        install()
        if not lcpcli_bus_is_ours():
            raise OSError(0, "another SIGBUS handler was installed; the map is not guarded")
        self.base = lcpcli_map(fd, length)
        if self.base == NULL:
            raise OSError("mmap failed")
        self.length = length
        self.slot = lcpcli_register(<uintptr_t>self.base, <uintptr_t>self.base + length)
        if self.slot < 0:
            lcpcli_unmap(self.base, length)
            self.base = NULL
            raise OSError(0, f"{LCPCLI_MAP_SLOTS} guarded maps are open already")

    def __dealloc__(self):
        if self.base != NULL:
            lcpcli_unregister(self.slot)
            lcpcli_unmap(self.base, self.length)
            self.base = NULL

    def __len__(self) -> int:
        return self.length

    def __getbuffer__(self, Py_buffer *view, int flags):
        if flags & PyBUF_WRITABLE:
            raise BufferError("a guarded map is read-only")
        self.shape[0] = <Py_ssize_t>self.length
        self.strides[0] = 1
        view.buf = self.base
        view.obj = self
        view.len = <Py_ssize_t>self.length
        view.readonly = 1
        view.itemsize = 1
        view.format = "B"
        view.ndim = 1
        view.shape = self.shape
        view.strides = self.strides
        view.suboffsets = NULL
        view.internal = NULL

    def __releasebuffer__(self, Py_buffer *view):
        pass

    def populate(self, size_t offset, size_t length) -> int:
        """Map the pages of bytes ``offset .. offset + length - 1`` now (reading them from
        the disk where the page cache has them not), the GIL released; 0 or the errno of
        ``madvise`` (EFAULT: part of the range is past the end of the file now)."""
        if offset > self.length or length > self.length - offset:
            raise ValueError("populate: the range is outside the map")
        cdef int err
        with nogil:
            err = lcpcli_populate(self.base, offset, length)
        return err

    def lost(self) -> int:
        """The lowest offset from which the map reads zeros because the file was truncated
        under it (a SIGBUS was met there), or -1 when every page read so far was the file's."""
        cdef uintptr_t value = lcpcli_lost(self.slot)
        return -1 if value == <uintptr_t>-1 else <Py_ssize_t>value

    def faults(self) -> int:
        """The SIGBUS faults the guard took in this map (one per first touch of a lost
        range; for tests)."""
        return <Py_ssize_t>lcpcli_faults(self.slot)

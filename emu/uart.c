/*
 * emu/uart.c -- UART0 of an emulated node as a pty or a loopback TCP port
 * (see uart.h).
 */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <unistd.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>

#include "sim_avr.h"
#include "sim_irq.h"
#include "avr_uart.h"

#include "uart.h"

#define OUTQ 65536                 /* bytes in flight on the line (power of 2) */
#define INQ  65536
#define IO_EVERY_NS 100000ull      /* host I/O at most every 100 us of emulated time */

/* ATmega1281 USART0 (data-space addresses) */
#define A_UCSR0A 0xC0
#define A_UCSR0B 0xC1
#define A_UCSR0C 0xC2
#define A_UBRR0L 0xC4
#define A_UBRR0H 0xC5
#define U2X0_BIT 1

enum { K_NULL, K_PTY, K_TCP };

typedef struct uart_ep {
    emu_node_t *node;
    int kind;
    int master, slave;             /* pty */
    int listen_fd, client;         /* tcp */
    char url[128];
    /* MCU -> host */
    uint8_t ob[OUTQ];
    uint64_t ot[OUTQ];
    uint32_t oh, otl;              /* head (next out), tail (next in) */
    uint64_t line_free_ns;
    /* host -> MCU */
    uint8_t ib[INQ];
    uint32_t ih, itl;
    uint64_t next_in_ns;
    int xoff;
    avr_irq_t *in_irq;
    uint64_t last_io_ns;
    avr_uart_t *sim;               /* simavr's USART0 */
    struct { avr_io_write_t c; void *param; } orig[4];
    uint64_t unread_from, unread_until;
    /* counters */
    uint64_t out_bytes, in_bytes, drop_unread, drop_full, drop_noclient, clients;
} uart_ep_t;

/* CPU cycles per character as the USART's registers say: start bit, 5-9
 * data bits, parity bit if enabled, 1 or 2 stop bits */
static uint32_t cycles_per_char(avr_t *avr)
{
    uint32_t ubrr = avr->data[A_UBRR0L] | ((avr->data[A_UBRR0H] & 0x0F) << 8);
    uint32_t per_bit = (ubrr + 1) * ((avr->data[A_UCSR0A] & (1 << U2X0_BIT)) ? 8 : 16);
    uint8_t c = avr->data[A_UCSR0C];
    int sz = ((c >> 1) & 3) | ((avr->data[A_UCSR0B] & 0x04) ? 4 : 0);
    static const int data_bits[8] = { 5, 6, 7, 8, 8, 8, 8, 9 };
    int bits = 1 + data_bits[sz] + ((c & 0x20) ? 1 : 0) + ((c & 0x08) ? 2 : 1);
    return per_bit * (uint32_t)bits;
}

static uint64_t byte_ns(uart_ep_t *u)
{
    avr_t *avr = u->node->avr;
    return (uint64_t)((double)cycles_per_char(avr) * 1e9 / (double)avr->frequency + 0.5);
}

/* simavr 1.6 recomputes its USART's character time only when UBRRnL is
 * written, ignores U2X written after it and always counts a parity bit
 * (11 bits for 8N1); keep its pump at the rate the registers give. */
static void rate_reg_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    uart_ep_t *u = param;
    int i = addr == A_UCSR0A ? 0 : addr == A_UCSR0C ? 1 : addr == A_UBRR0L ? 2 : 3;
    if (u->orig[i].c)
        u->orig[i].c(avr, addr, v, u->orig[i].param);
    else
        avr_core_watch_write(avr, addr, v);
    if (u->sim)
        u->sim->cycles_per_byte = cycles_per_char(avr);
}

static void hook_rate(uart_ep_t *u)
{
    avr_t *avr = u->node->avr;
    for (avr_io_t *io = avr->io_port; io; io = io->next)
        if (io->kind && !strcmp(io->kind, "uart") && ((avr_uart_t *)io)->name == '0')
            u->sim = (avr_uart_t *)io;
    static const avr_io_addr_t regs[4] = { A_UCSR0A, A_UCSR0C, A_UBRR0L, A_UBRR0H };
    for (int i = 0; i < 4; i++) {
        avr_io_addr_t a = AVR_DATA_TO_IO(regs[i]);
        u->orig[i].c = avr->io[a].w.c;
        u->orig[i].param = avr->io[a].w.param;
        avr->io[a].w.c = rate_reg_write;
        avr->io[a].w.param = u;
    }
}

static void on_output(avr_irq_t *irq, uint32_t v, void *param)
{
    uart_ep_t *u = param;
    (void)irq;
    uint64_t now = emu_node_now_ns(u->node);
    uint64_t start = u->line_free_ns > now ? u->line_free_ns : now;
    uint64_t due = start + byte_ns(u);
    u->line_free_ns = due;
    if (u->otl - u->oh >= OUTQ) {          /* cannot happen at line rate */
        u->drop_full++;
        return;
    }
    u->ob[u->otl & (OUTQ - 1)] = (uint8_t)v;
    u->ot[u->otl & (OUTQ - 1)] = due;
    u->otl++;
}

static void on_xon(avr_irq_t *irq, uint32_t v, void *param)
{
    uart_ep_t *u = param;
    (void)irq;
    if (v)
        u->xoff = 0;
}

static void on_xoff(avr_irq_t *irq, uint32_t v, void *param)
{
    uart_ep_t *u = param;
    (void)irq;
    u->xoff = v != 0;
}

static int set_nonblock(int fd)
{
    int fl = fcntl(fd, F_GETFL);
    return fl < 0 ? -1 : fcntl(fd, F_SETFL, fl | O_NONBLOCK);
}

static int open_pty(uart_ep_t *u)
{
    int m = posix_openpt(O_RDWR | O_NOCTTY);
    if (m < 0 || grantpt(m) || unlockpt(m))
        return -1;
    const char *name = ptsname(m);
    if (!name)
        return -1;
    snprintf(u->url, sizeof u->url, "%s", name);
    /* keep one slave descriptor open: the master then never sees EIO/hang-up
     * when a host program closes the port, and the line settings stay */
    int s = open(name, O_RDWR | O_NOCTTY);
    if (s < 0)
        return -1;
    struct termios t;
    if (tcgetattr(s, &t) == 0) {
        cfmakeraw(&t);
        tcsetattr(s, TCSANOW, &t);
    }
    set_nonblock(m);
    u->master = m;
    u->slave = s;
    return 0;
}

static int open_tcp(uart_ep_t *u, int port)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    if (fd < 0)
        return -1;
    int one = 1;
    setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_port = htons((uint16_t)port);
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (bind(fd, (struct sockaddr *)&a, sizeof a) || listen(fd, 1)) {
        close(fd);
        return -1;
    }
    socklen_t len = sizeof a;
    getsockname(fd, (struct sockaddr *)&a, &len);
    set_nonblock(fd);
    u->listen_fd = fd;
    snprintf(u->url, sizeof u->url, "socket://127.0.0.1:%u", ntohs(a.sin_port));
    return 0;
}

int uart_attach(emu_node_t *node, const char *spec)
{
    uart_ep_t *u = calloc(1, sizeof *u);
    if (!u)
        return -1;
    u->node = node;
    u->master = u->slave = u->listen_fd = u->client = -1;
    if (!strcmp(spec, "null")) {
        u->kind = K_NULL;
    } else if (!strcmp(spec, "pty")) {
        u->kind = K_PTY;
        if (open_pty(u)) {
            fprintf(stderr, "ninedof-emu: cannot create a pseudo-terminal: %s\n", strerror(errno));
            free(u);
            return -1;
        }
    } else if (!strncmp(spec, "tcp:", 4)) {
        char *end;
        long port = strtol(spec + 4, &end, 10);
        if (*end || end == spec + 4 || port < 0 || port > 65535) {
            fprintf(stderr, "ninedof-emu: bad serial spec '%s' (pty, tcp:PORT or null)\n", spec);
            free(u);
            return -1;
        }
        u->kind = K_TCP;
        if (open_tcp(u, (int)port)) {
            fprintf(stderr, "ninedof-emu: cannot listen on 127.0.0.1:%ld: %s\n", port, strerror(errno));
            free(u);
            return -1;
        }
    } else {
        fprintf(stderr, "ninedof-emu: bad serial spec '%s' (pty, tcp:PORT or null)\n", spec);
        free(u);
        return -1;
    }
    avr_t *avr = node->avr;
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT), on_output, u);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XON), on_xon, u);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XOFF), on_xoff, u);
    u->in_irq = avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
    hook_rate(u);
    node->uart = u;
    if (u->kind != K_NULL) {
        printf("%s\n", u->url);
        fflush(stdout);
    }
    return 0;
}

const char *uart_url(emu_node_t *node)
{
    uart_ep_t *u = node->uart;
    return u ? u->url : "";
}

void uart_set_unread(emu_node_t *node, uint64_t from_ns, uint64_t until_ns)
{
    uart_ep_t *u = node->uart;
    if (!u)
        return;
    u->unread_from = from_ns;
    u->unread_until = until_ns;
}

/* write what we can; what the host cannot take now is dropped */
static void host_write(uart_ep_t *u, const uint8_t *b, size_t n)
{
    int fd = u->kind == K_PTY ? u->master : u->client;
    if (fd < 0) {
        u->drop_noclient += n;
        return;
    }
    size_t done = 0;
    while (done < n) {
        ssize_t w = write(fd, b + done, n - done);
        if (w > 0) {
            done += (size_t)w;
            continue;
        }
        if (w < 0 && errno == EINTR)
            continue;
        if (w < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
            u->drop_full += n - done;
        } else if (u->kind == K_TCP) {        /* client went away */
            close(u->client);
            u->client = -1;
            u->drop_noclient += n - done;
        } else {
            u->drop_full += n - done;
        }
        break;
    }
    u->out_bytes += done;
}

static void host_io(uart_ep_t *u, const uint8_t *b, size_t n)
{
    if (u->kind == K_TCP) {
        int c = accept(u->listen_fd, NULL, NULL);
        if (c >= 0) {                        /* a new client replaces the old one */
            if (u->client >= 0)
                close(u->client);
            set_nonblock(c);
            int one = 1;
            setsockopt(c, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
            u->client = c;
            u->clients++;
        }
    }
    if (n)
        host_write(u, b, n);
    int fd = u->kind == K_PTY ? u->master : u->client;
    while (fd >= 0) {
        uint32_t used = u->itl - u->ih;
        if (used >= INQ)
            break;
        uint8_t tmp[4096];
        size_t room = INQ - used;
        ssize_t r = read(fd, tmp, room < sizeof tmp ? room : sizeof tmp);
        if (r > 0) {
            for (ssize_t i = 0; i < r; i++)
                u->ib[(u->itl++) & (INQ - 1)] = tmp[i];
            continue;
        }
        if (r == 0 && u->kind == K_TCP) {   /* client closed */
            close(u->client);
            u->client = -1;
        }
        break;
    }
}

void uart_poll(emu_node_t *node, uint64_t now)
{
    uart_ep_t *u = node->uart;
    if (!u)
        return;
    /* host -> MCU at the line rate, while simavr's FIFO has room */
    if (u->ih != u->itl && !u->xoff && now >= u->next_in_ns) {
        uint8_t b = u->ib[(u->ih++) & (INQ - 1)];
        avr_raise_irq(u->in_irq, b);
        u->in_bytes++;
        uint64_t bn = byte_ns(u);
        u->next_in_ns = (u->next_in_ns + bn > now ? u->next_in_ns : now) + bn;
    }
    if (now - u->last_io_ns < IO_EVERY_NS && u->otl - u->oh < 1024)
        return;
    u->last_io_ns = now;
    uint8_t buf[4096];
    size_t n = 0;
    while (u->oh != u->otl && u->ot[u->oh & (OUTQ - 1)] <= now) {
        uint64_t due = u->ot[u->oh & (OUTQ - 1)];
        uint8_t b = u->ob[u->oh & (OUTQ - 1)];
        u->oh++;
        if (u->kind == K_NULL) {
            u->out_bytes++;
            continue;
        }
        if (due >= u->unread_from && due < u->unread_until) {
            u->drop_unread++;
            continue;
        }
        buf[n++] = b;
        if (n == sizeof buf) {
            host_io(u, buf, n);
            n = 0;
        }
    }
    if (u->kind != K_NULL)
        host_io(u, buf, n);
}

void uart_stats(emu_node_t *node, FILE *out)
{
    uart_ep_t *u = node->uart;
    if (!u)
        return;
    fprintf(out, "uart node %d: url=%s out=%llu in=%llu dropped_unread=%llu dropped_full=%llu "
            "dropped_noclient=%llu clients=%llu\n", node->index, u->kind == K_NULL ? "null" : u->url,
            (unsigned long long)u->out_bytes, (unsigned long long)u->in_bytes,
            (unsigned long long)u->drop_unread, (unsigned long long)u->drop_full,
            (unsigned long long)u->drop_noclient, (unsigned long long)u->clients);
}

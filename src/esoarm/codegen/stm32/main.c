/* esoarm on board on an STM32F401 (Nucleo-F401RE), register level, no HAL or CMSIS.
 *
 * The generated observer and controller (esoarm_controller.c) run in the sample timer's
 * interrupt and drive the motor; the host ('esoarm run SCENARIO --port PATH --onboard')
 * starts, supervises and logs over the rig protocol (esoarm_protocol.h, as the Uno firmware).
 *
 *   clock   HSI 16 MHz -> PLL 84 MHz (SYSCLK, AHB), APB1 42 MHz (its timers 84 MHz)
 *   encoder TIM2 in encoder mode (x4, both edges), A = PA0 (AF1), B = PA1 (AF1), pull-ups;
 *           32-bit counter, read once per sample
 *   motor   TIM3 CH1 PWM on PA6 (AF2) at about 20 kHz (L298N ENA), IN1 = PA8, IN2 = PA9;
 *           duty in counts of PWM_MAX, its sign on IN1/IN2 (IN1 high = positive)
 *   sample  TIM4 update interrupt every SAMPLE_PERIOD_US (1 MHz ticks)
 *   link    USART2, PA2 TX / PA3 RX (AF7): the ST-LINK's virtual COM port on a Nucleo
 *
 * Faults turn the motor off until the next START and are reported: the watchdog (no
 * HEARTBEAT for 100 ms), an overrun (a sample due while the previous one is being
 * stepped, or the stream RING - 1 samples behind), a DUTY or TORQUE frame (the chip runs
 * its own controller).
 */
#include <stdint.h>
#include "esoarm_protocol.h"
#include "esoarm_controller.h"
#include "esoarm_reference.h"
#include "esoarm_board.h"

#define REG(a) (*(volatile uint32_t *)(a))
/* RCC, flash (RM0368 section 6, 3) */
#define RCC_CR REG(0x40023800u)
#define RCC_PLLCFGR REG(0x40023804u)
#define RCC_CFGR REG(0x40023808u)
#define RCC_AHB1ENR REG(0x40023830u)
#define RCC_APB1ENR REG(0x40023840u)
#define FLASH_ACR REG(0x40023C00u)
/* GPIOA (section 8) */
#define GPIOA 0x40020000u
#define GPIO_MODER(p) REG((p) + 0x00u)
#define GPIO_PUPDR(p) REG((p) + 0x0Cu)
#define GPIO_BSRR(p) REG((p) + 0x18u)
#define GPIO_AFRL(p) REG((p) + 0x20u)
/* general-purpose timers (section 13) */
#define TIM2 0x40000000u
#define TIM3 0x40000400u
#define TIM4 0x40000800u
#define TIM_CR1(t) REG((t) + 0x00u)
#define TIM_SMCR(t) REG((t) + 0x08u)
#define TIM_DIER(t) REG((t) + 0x0Cu)
#define TIM_SR(t) REG((t) + 0x10u)
#define TIM_EGR(t) REG((t) + 0x14u)
#define TIM_CCMR1(t) REG((t) + 0x18u)
#define TIM_CCER(t) REG((t) + 0x20u)
#define TIM_CNT(t) REG((t) + 0x24u)
#define TIM_PSC(t) REG((t) + 0x28u)
#define TIM_ARR(t) REG((t) + 0x2Cu)
#define TIM_CCR1(t) REG((t) + 0x34u)
/* USART2 (section 19) */
#define USART2_SR REG(0x40004400u)
#define USART2_DR REG(0x40004404u)
#define USART2_BRR REG(0x40004408u)
#define USART2_CR1 REG(0x4000440Cu)
/* NVIC */
#define NVIC_ISER0 REG(0xE000E100u)
#define NVIC_ISER1 REG(0xE000E104u)
#define NVIC_IPR(n) (*(volatile uint8_t *)(0xE000E400u + (n)))
#define TIM4_IRQ 30u
#define USART2_IRQ 38u
#define RX_RING 64u

#define SYSCLK_HZ 84000000UL
#define APB1_HZ 42000000UL
#define TIMER_HZ 84000000UL /* APB1 timers: twice APB1 when APB1 is divided */
#define WATCHDOG_US 100000UL
#define RING 8u

static esoarm_state ctl;
static esoarm_reference ref;  /* the scenario's moves, from START */
static const esoarm_real COUNT_TO_RAD = (esoarm_real)(6.283185307179586 / COUNTS_PER_REV);
static const char SCENARIO_HASH8[8] = {ESOARM_SCENARIO_HASH[0], ESOARM_SCENARIO_HASH[1],
    ESOARM_SCENARIO_HASH[2], ESOARM_SCENARIO_HASH[3], ESOARM_SCENARIO_HASH[4],
    ESOARM_SCENARIO_HASH[5], ESOARM_SCENARIO_HASH[6], ESOARM_SCENARIO_HASH[7]};

typedef struct {
    uint32_t k;
    int32_t count;
    float u, z1, z2, z3;
    int16_t duty;
} record_t;
static record_t ring[RING];
static volatile uint32_t ring_head, ring_tail; /* the interrupt writes head, main() tail */
static volatile uint8_t running, stepping, pending_fault;
static volatile uint32_t pending_detail, sample_k, beat_k, count0;
static eso_parser_t parser;
static uint8_t frame_buf[ESO_MAX_FRAME];
static uint8_t tx_seq;
static volatile uint8_t rx_ring[RX_RING];
static volatile uint32_t rx_head, rx_tail; /* the receive interrupt writes head */

static void clock_init(void)
{
    RCC_CR |= 1u;                              /* HSION */
    while (!(RCC_CR & (1u << 1))) {}           /* HSIRDY */
    /* PLL from HSI: M = 16 (1 MHz), N = 336, P = 4 (84 MHz), Q = 7 */
    RCC_PLLCFGR = 16u | (336u << 6) | (1u << 16) | (7u << 24);
    RCC_CR |= 1u << 24;                        /* PLLON */
    while (!(RCC_CR & (1u << 25))) {}          /* PLLRDY */
    FLASH_ACR = 2u | (1u << 8) | (1u << 9) | (1u << 10); /* 2 wait states, prefetch, caches */
    RCC_CFGR = (4u << 10) | 2u;                /* APB1 = HCLK / 2, SYSCLK = PLL */
    while (((RCC_CFGR >> 2) & 3u) != 2u) {}
}

static void gpio_af(uint32_t pin, uint32_t af)
{
    GPIO_MODER(GPIOA) = (GPIO_MODER(GPIOA) & ~(3u << (2u * pin))) | (2u << (2u * pin));
    GPIO_AFRL(GPIOA) = (GPIO_AFRL(GPIOA) & ~(0xFu << (4u * pin))) | (af << (4u * pin));
}

static void peripherals_init(void)
{
    RCC_AHB1ENR |= 1u;                         /* GPIOA */
    RCC_APB1ENR |= (1u << 0) | (1u << 1) | (1u << 2) | (1u << 17); /* TIM2, TIM3, TIM4, USART2 */
    /* encoder: PA0, PA1 as TIM2_CH1/CH2 with pull-ups; encoder mode 3, input filter 3 */
    gpio_af(0u, 1u);
    gpio_af(1u, 1u);
    GPIO_PUPDR(GPIOA) = (GPIO_PUPDR(GPIOA) & ~0xFu) | 0x5u;
    TIM_CCMR1(TIM2) = 1u | (3u << 4) | (1u << 8) | (3u << 12);
    TIM_CCER(TIM2) = 0u;
    TIM_SMCR(TIM2) = 3u;
    TIM_ARR(TIM2) = 0xFFFFFFFFu;
    TIM_CR1(TIM2) = 1u;
    /* motor: PA6 TIM3_CH1 PWM mode 1, preload; PA8, PA9 outputs, low */
    gpio_af(6u, 2u);
    GPIO_BSRR(GPIOA) = (1u << (8u + 16u)) | (1u << (9u + 16u));
    GPIO_MODER(GPIOA) = (GPIO_MODER(GPIOA) & ~((3u << 16) | (3u << 18))) | (1u << 16) | (1u << 18);
    TIM_PSC(TIM3) = (uint32_t)(TIMER_HZ / (20000UL * (PWM_MAX + 1UL))) - 1u;
    TIM_ARR(TIM3) = PWM_MAX;
    TIM_CCR1(TIM3) = 0u;
    TIM_CCMR1(TIM3) = (6u << 4) | (1u << 3);
    TIM_CCER(TIM3) = 1u;
    TIM_EGR(TIM3) = 1u;
    TIM_CR1(TIM3) = (1u << 7) | 1u;
    /* the link: USART2 on PA2/PA3 (AF7), 8N1, oversampling by 16 */
    gpio_af(2u, 7u);
    gpio_af(3u, 7u);
    USART2_BRR = (uint32_t)((APB1_HZ + BAUD / 2UL) / BAUD);
    USART2_CR1 = (1u << 13) | (1u << 5) | (1u << 3) | (1u << 2); /* UE, RXNEIE, TE, RE */
    NVIC_IPR(USART2_IRQ) = 0x20u; /* above the sample tick: no byte lost while it steps */
    NVIC_ISER1 = 1u << (USART2_IRQ - 32u);
    /* the sample clock: TIM4 at 1 MHz, an update every SAMPLE_PERIOD_US */
    TIM_PSC(TIM4) = (uint32_t)(TIMER_HZ / 1000000UL) - 1u;
    TIM_ARR(TIM4) = SAMPLE_PERIOD_US - 1u;
    TIM_EGR(TIM4) = 1u;
    TIM_SR(TIM4) = 0u;
    TIM_DIER(TIM4) = 1u;
    NVIC_IPR(TIM4_IRQ) = 0x40u;
    NVIC_ISER0 = 1u << TIM4_IRQ;
    TIM_CR1(TIM4) = 1u;
}

static void motor_write(int32_t duty)
{
    if (duty > (int32_t)PWM_MAX) duty = (int32_t)PWM_MAX;
    if (duty < -(int32_t)PWM_MAX) duty = -(int32_t)PWM_MAX;
    if (duty > 0) GPIO_BSRR(GPIOA) = (1u << 8) | (1u << (9u + 16u));
    else if (duty < 0) GPIO_BSRR(GPIOA) = (1u << 9) | (1u << (8u + 16u));
    else GPIO_BSRR(GPIOA) = (1u << (8u + 16u)) | (1u << (9u + 16u));
    TIM_CCR1(TIM3) = (uint32_t)(duty < 0 ? -duty : duty);
}

static void halt_from_isr(uint8_t code, uint32_t detail)
{
    motor_write(0);
    running = 0u;
    if (!pending_fault) {
        pending_fault = code;
        pending_detail = detail;
    }
}

/* The sample tick: read the encoder, step the controller, write the motor, record. */
void TIM4_IRQHandler(void);
void TIM4_IRQHandler(void)
{
    uint32_t k;
    int32_t count;
    int16_t duty;
    TIM_SR(TIM4) = 0u;
    if (!running) return;
    if (stepping) { /* cannot happen at one priority level; kept for a nested build */
        halt_from_isr(ESO_FAULT_OVERRUN, sample_k);
        return;
    }
    k = sample_k;
    if ((k - beat_k) * (uint32_t)SAMPLE_PERIOD_US > WATCHDOG_US) {
        halt_from_isr(ESO_FAULT_WATCHDOG, k);
        return;
    }
    stepping = 1u;
    count = (int32_t)(TIM_CNT(TIM2) - count0);
    {
        esoarm_real r[3];
        esoarm_reference_next(&ref, r);
        (void)esoarm_step(&ctl, (esoarm_real)count * COUNT_TO_RAD, r[0], r[1], r[2]);
    }
    duty = (int16_t)ctl.duty;
    motor_write(duty);
    if ((ring_head + 1u) % RING == ring_tail) {
        halt_from_isr(ESO_FAULT_OVERRUN, k); /* main() cannot stream as fast as we sample */
    } else {
        record_t *r = &ring[ring_head];
        r->k = k;
        r->count = count;
        r->u = (float)ctl.applied;
        r->z1 = (float)ctl.zhat[0];
        r->z2 = (float)ctl.zhat[1];
        r->z3 = (float)ctl.zhat[2];
        r->duty = duty;
        ring_head = (ring_head + 1u) % RING;
    }
    sample_k = k + 1u;
    stepping = 0u;
    if (TIM_SR(TIM4) & 1u) halt_from_isr(ESO_FAULT_OVERRUN, k); /* the next tick came */
}

/* Received bytes into a ring: the USART holds one byte, a frame on the wire meanwhile
 * would overrun it. */
void USART2_IRQHandler(void);
void USART2_IRQHandler(void)
{
    uint32_t sr = USART2_SR;
    uint8_t b = (uint8_t)USART2_DR; /* reading SR then DR clears RXNE and ORE */
    if (sr & (1u << 5)) {
        uint32_t next = (rx_head + 1u) % RX_RING;
        if (next != rx_tail) {
            rx_ring[rx_head] = b;
            rx_head = next;
        }
    }
}

static void put(const uint8_t *p, uint32_t n)
{
    while (n--) {
        while (!(USART2_SR & (1u << 7))) {} /* TXE */
        USART2_DR = *p++;
    }
}

static void send_frame(uint8_t len)
{
    if (len) put(frame_buf, len);
    tx_seq++;
}

static void irq_off(void) { __asm volatile("cpsid i" ::: "memory"); }
static void irq_on(void) { __asm volatile("cpsie i" ::: "memory"); }

static void handle_frame(const eso_frame_t *f)
{
    switch (f->type) {
    case ESO_HELLO:
        send_frame(eso_encode_info(frame_buf, tx_seq, ESO_FLAG_ONBOARD, COUNTS_PER_REV,
                                   PWM_MAX, SAMPLE_PERIOD_US));
        send_frame(eso_encode_chip_info(frame_buf, tx_seq, 1u, ONBOARD_SUMS, SCENARIO_HASH8));
        break;
    case ESO_START:
        irq_off();
        running = 0u;
        motor_write(0);
        esoarm_init(&ctl);
        esoarm_reference_init(&ref);
        count0 = TIM_CNT(TIM2); /* the angle at START is theta = 0 */
        sample_k = 0u;
        beat_k = 0u;
        ring_head = ring_tail = 0u;
        pending_fault = 0u;
        TIM_CNT(TIM4) = SAMPLE_PERIOD_US - 1u; /* sample 0 at the next microsecond */
        running = 1u;
        irq_on();
        break;
    case ESO_HEARTBEAT:
        irq_off();
        if (running) beat_k = sample_k;
        irq_on();
        break;
    case ESO_STOP:
        irq_off();
        running = 0u;
        motor_write(0);
        irq_on();
        send_frame(eso_encode(frame_buf, ESO_STOPPED, tx_seq, 0, 0));
        break;
    default: /* DUTY, TORQUE: the chip runs its own controller */
        irq_off();
        halt_from_isr(ESO_FAULT_BAD_COMMAND, f->type);
        irq_on();
        break;
    }
}

int main(void)
{
    eso_frame_t f;
    clock_init();
    peripherals_init();
    eso_parser_init(&parser);
    for (;;) {
        while (rx_tail != rx_head) {
            eso_parser_push(&parser, rx_ring[rx_tail]);
            rx_tail = (rx_tail + 1u) % RX_RING;
            while (eso_parser_next(&parser, &f)) handle_frame(&f);
        }
        while (ring_tail != ring_head) { /* stream what the interrupt recorded */
            record_t r = ring[ring_tail];
            ring_tail = (ring_tail + 1u) % RING;
            send_frame(eso_encode_chip_sample(frame_buf, tx_seq, r.k,
                                              r.k * (uint32_t)SAMPLE_PERIOD_US, r.count, r.u,
                                              r.z1, r.z2, r.z3, r.duty));
        }
        if (pending_fault) {
            uint8_t code;
            uint32_t detail;
            irq_off();
            code = pending_fault;
            detail = pending_detail;
            pending_fault = 0u;
            irq_on();
            send_frame(eso_encode_fault(frame_buf, tx_seq, code, detail));
        }
    }
}
